#pragma once
// Surface decimation under a distance bound, as the seed decimates its CT and laser-scan
// surfaces (Kobbelt's one-sided Hausdorff criterion): CGAL's edge-collapse simplification with
// Lindstrom-Turk cost and placement and the polyhedral envelope filter, which refuses any
// collapse after which a triangle leaves the envelope of the input at the bound: the one-sided
// Hausdorff distance from the result to the input stays within it (Kobbelt's criterion). The
// result is measured both ways with CGAL's bounded-error Hausdorff distance.

#include <array>
#include <cstdint>

#include "incise/io/mesh_io.hpp"

namespace incise::planning {

/// A surface decimated under a bound, with its two-sided distances to the input.
struct DecimationResult {
  SurfaceMesh surface;                ///< the decimated surface
  std::size_t triangles_before = 0;   ///< of the largest component
  std::size_t triangles_after = 0;    ///< of the decimated surface
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

/// How remesh_surface meshes a surface again (the default method of surface-file plans).
struct RemeshOptions {
  double max_error = 0.0;   ///< the bound: each triangle's centre within it of the surface
  double facet_size = 0.0;  ///< largest triangle circumradius, in the surface's units
  std::uint32_t seed = 0;   ///< the mesher's random seed (results repeat for a seed)
};

/// A surface meshed again from its signed-distance image, with what was filled or left out.
struct RemeshResult {
  SurfaceMesh surface;                        ///< the new surface
  std::size_t triangles_before = 0;           ///< of the largest component
  std::size_t triangles_after = 0;            ///< of the new surface
  std::size_t holes_filled = 0;               ///< open borders closed for the mesher
  std::size_t triangles_over_holes = 0;       ///< meshed over a filled hole, left out
  std::size_t pieces_left_out_triangles = 0;  ///< in pieces apart from the largest
  std::array<std::size_t, 3> grid{};          ///< voxels of the level-set image
};

/// Remeshes the largest connected component within a distance bound (its largest piece kept), as
/// the CT's isosurfaces are meshed: the surface (its holes filled) becomes the zero level set of a
/// signed distance image, which CGAL's mesher meets to within `max_error` (each triangle's
/// circumcentre, along its dual Voronoi edge), with triangles no larger than `facet_size`.
/// Triangles over the filled holes are left out. Seconds for a 200,000-triangle surface where the
/// envelope decimation takes minutes; the bound holds at the triangles' centres, not everywhere, so
/// the caller measures the distance both ways (measure_surface_distance).
[[nodiscard]] RemeshResult remesh_within_bound(const SurfaceMesh& surface,
                                               const RemeshOptions& options);

}  // namespace incise::planning
