#pragma once
// Repair of triangle surfaces as they come from public repositories and other tools, so that
// they bound a volume TetGen can fill: CGAL's Polygon Mesh Processing in place (merge duplicate
// points and triangles, drop degenerate ones, orient, split non-manifold vertices, stitch
// borders, fill holes), and for what cannot be repaired in place (self-intersections) CGAL's
// 3D Alpha Wrapping: a watertight, manifold, self-intersection-free surface around the input,
// at a stated offset. Every change is reported, with the largest distance between the result
// and the input.

#include <string>
#include <vector>

#include "incise/io/mesh_io.hpp"

namespace incise {

/// How `incise mesh --repair` mends a surface before meshing it.
struct SurfaceRepairOptions {
  /// kNone: refuse what is not clean (no change); kInPlace: repair in place only; kAuto: in
  /// place, then a wrap if that was not enough; kWrap: always wrap.
  enum class Mode { kNone, kInPlace, kAuto, kWrap };
  Mode mode = Mode::kAuto;  ///< how far the repair may go
  /// Alpha wrapping: the largest cavity or gap left out (alpha) and how far outside the input
  /// the wrap lies (offset), in surface units; 0: the bounding box diagonal / 100 and / 1000.
  double wrap_alpha = 0.0;
  double wrap_offset = 0.0;  ///< see wrap_alpha
};

/// What a repair did to a surface (`incise mesh`'s report).
struct SurfaceRepairReport {
  bool changed = false;               ///< the surface returned differs from the input
  std::size_t points_merged = 0;      ///< duplicate points joined
  std::size_t triangles_removed = 0;  ///< duplicate or degenerate triangles dropped
  std::size_t vertices_split = 0;     ///< non-manifold vertices given one copy per fan
  std::size_t edges_stitched = 0;     ///< border edge pairs joined
  std::size_t holes_filled = 0;       ///< open borders closed
  double hole_area = 0.0;             ///< surface units squared, all filled holes together
  double largest_hole_area = 0.0;     ///< surface units squared
  bool reoriented = false;            ///< turned to bound its volume outward
  bool wrapped = false;               ///< replaced by an alpha wrap
  double alpha = 0.0;                 ///< of the wrap (surface units)
  double offset = 0.0;                ///< of the wrap (surface units)
  /// Largest distance from a result vertex to the input surface, and from an input vertex to
  /// the result (surface units): how far the repair moved the surface, measured at vertices.
  double result_to_input = 0.0;
  double input_to_result = 0.0;    ///< see result_to_input
  std::vector<std::string> notes;  ///< one line per change, for the user
  /// Why the in-place repair stopped short of a surface (empty when it did not).
  std::string failure;
};

/// Returns `surface` as it is when it is already closed and clean (report.changed false);
/// otherwise repaired as `options` says. Throws InputError, naming what is left, when the mode
/// does not allow the repair it needs.
[[nodiscard]] SurfaceMesh repair_surface(const SurfaceMesh& surface,
                                         const SurfaceRepairOptions& options,
                                         SurfaceRepairReport& report);

}  // namespace incise
