#pragma once
// Surface decimation under a distance bound, as the seed decimates its CT and laser-scan
// surfaces (Kobbelt's one-sided Hausdorff criterion): CGAL's edge-collapse simplification with
// Lindstrom-Turk cost and placement and the polyhedral envelope filter, which refuses any
// collapse after which a triangle leaves the envelope of the input at the bound: the one-sided
// Hausdorff distance from the result to the input stays within it (Kobbelt's criterion). The
// result is measured both ways with CGAL's bounded-error Hausdorff distance.

#include "incise/io/mesh_io.hpp"

namespace incise::planning {

struct DecimationResult {
  SurfaceMesh surface;
  std::size_t triangles_before = 0;
  std::size_t triangles_after = 0;
  double hausdorff_to_input = 0.0;    ///< m: from the decimated surface to the input
  double hausdorff_from_input = 0.0;  ///< m: from the input to the decimated surface
};

/// Keeps the largest connected component, then decimates it keeping every triangle within
/// `max_error` (m) of it. Throws InputError when the surface is not a manifold CGAL can
/// simplify.
[[nodiscard]] DecimationResult decimate_surface(const SurfaceMesh& surface, double max_error);

/// The largest connected component (by triangles; triangles joined through shared edges; of
/// equal ones, the first in triangle order).
[[nodiscard]] SurfaceMesh largest_component(const SurfaceMesh& surface);

}  // namespace incise::planning
