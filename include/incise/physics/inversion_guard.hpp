#pragma once
// Keeps tetrahedra right side out at the end of a step. A finite volume penalty cannot hold a
// sliver (a subdivision cut's thin child has almost no volume to defend and its springs do not
// resist a corner passing through the opposite face), so after each step a tetrahedron whose
// volume fell below half a share of its rest volume is pushed back to that share, as position-based
// dynamics projects an inequality constraint: its free corners move along the volume gradient,
// each in inverse proportion to its mass (the centre of mass stays), and the velocity that
// still closes it is removed the same way (an inelastic stop: momentum kept, kinetic energy
// only lost). Only the few tetrahedra below the share are touched. Where projection cannot
// settle (a fan of tetrahedra wound the wrong way round an edge), the corners of those still
// inside out are moved back towards where the step started, which was right side out.

#include <cstddef>
#include <functional>
#include <span>

#include "incise/core/types.hpp"

namespace incise {

class TetMesh;

/// How hard the inversion guard pushes tetrahedra back right side out (scene key
/// `model.inversion_guard`).
struct InversionGuardParameters {
  /// A tetrahedron below half this share of its rest volume is pushed back to it
  /// (dimensionless, in [0, 1)); 0 turns the guard off.
  double min_volume_ratio = 0.05;
  /// Passes over the tetrahedra still below their share (each pass projects them in turn)
  /// before the fallback.
  int max_passes = 200;
};

/// What one call of keep_right_side_out did.
struct InversionGuardOutcome {
  std::size_t corrected = 0;  ///< tetrahedra pushed back (counted once per call)
  /// Vertices the fallback moved back towards the start of the step.
  std::size_t backtracked = 0;
  /// With a volume <= 0 at the end (only with corners whose motion is prescribed).
  std::size_t left_inverted = 0;
};

/// Pushes every tetrahedron of `mesh` whose volume at `x` is below half min_volume_ratio times
/// its rest volume back to that ratio; `masses` (kg) weigh the corners and `fixed` vertices do not
/// move. `start` holds the positions the step started from, every tetrahedron right side out
/// there (empty: no fallback; vertices beyond its size are not moved back). x in m, v in m/s.
InversionGuardOutcome keep_right_side_out(const TetMesh& mesh, std::span<const double> masses,
                                          const std::function<bool(VertexId)>& fixed,
                                          const InversionGuardParameters& parameters,
                                          std::span<const Vec3> start, std::span<Vec3> x,
                                          std::span<Vec3> v);

}  // namespace incise
