#pragma once
// What other threads see of a running engine: an immutable snapshot published once per frame.
// A viewer or a 1 kHz device loop takes the latest with SnapshotChannel::latest() and keeps it
// as long as it likes; the physics never waits for a reader and a reader never sees a
// half-written frame.

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "incise/core/shared_slot.hpp"
#include "incise/cut/blade.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// The boundary surface's triangles (outward, vertex ids into the snapshot's positions), each
/// marked when it lies on a cut. Shared by consecutive snapshots while the mesh is unchanged.
struct SurfaceTopology {
  std::uint64_t mesh_revision = 0;  ///< the mesh's revision it was built from
  /// Grows with every rebuild (a cutter's move can re-mark faces without editing the mesh).
  std::uint64_t version = 0;
  std::vector<Triangle> triangles;   ///< outward, vertex ids
  std::vector<std::uint8_t> on_cut;  ///< 1: a face the cut opened; 0: the exterior
  /// Rest positions of every mesh vertex (m): where solid textures are looked up.
  std::vector<Vec3> rest_positions;
};

/// A tetrahedron the blade is in (the seed's active tetrahedra), with which corners lie on
/// the cut (bit k: corner k).
struct ActiveTet {
  Tet vertices;             ///< its corners (vertex ids)
  std::uint8_t on_cut = 0;  ///< bit k: corner k lies on the cut
};

/// One frame of a running engine as other threads see it: immutable once published.
struct Snapshot {
  int frame = 0;                                   ///< the frame it shows
  double time = 0.0;                               ///< s
  std::vector<Vec3> positions;                     ///< current positions (m), one per mesh vertex
  std::shared_ptr<const SurfaceTopology> surface;  ///< the boundary to draw
  std::optional<BladePose> blade;                  ///< the blade at the end of the frame, if any
  double cd = 0.0;                                 ///< the frame's stage times (s)
  double gc = 0.0;                                 ///< s
  double rx = 0.0;                                 ///< s
  std::size_t tets = 0;                            ///< tetrahedra in the mesh
  std::vector<ActiveTet> active;                   ///< the tetrahedra the blade is in
  /// The embedded visual surface (scene `visual`), drawn instead of `surface` when present:
  /// its triangles index `visual_positions` (m), its rest positions are the surface's own.
  std::shared_ptr<const SurfaceTopology> visual_surface;
  std::vector<Vec3> visual_positions;  ///< m, one per point of the visual surface
};

/// One published snapshot at a time, swapped under a lock held only to copy its pointer.
class SnapshotChannel {
 public:
  /// Makes `snapshot` the newest (the engine's thread).
  void publish(std::shared_ptr<const Snapshot> snapshot) { latest_.store(std::move(snapshot)); }
  /// The newest snapshot (null before the first publish). Safe from any thread.
  [[nodiscard]] std::shared_ptr<const Snapshot> latest() const { return latest_.load(); }

 private:
  SharedSlot<const Snapshot> latest_;
};

}  // namespace incise
