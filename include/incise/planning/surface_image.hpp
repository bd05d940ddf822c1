#pragma once
// A closed triangle surface as an image of signed distance, so that the CT's isosurface mesher
// can remesh a surface file within a distance bound.

#include "incise/imaging/volume_image.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::planning {

/// The signed distance (mm; positive inside) to a closed, consistently oriented surface (mm), on
/// a grid of `spacing` (mm) covering it with a margin of three voxels. Exact within two voxels
/// of the surface, where the level set at 0 lies; clamped to +-2 spacings beyond. Inside is
/// decided by ray parity along rows of the grid. Parallel.
[[nodiscard]] imaging::VolumeImage signed_distance_image(const SurfaceMesh& closed_surface,
                                                         double spacing);

}  // namespace incise::planning
