#pragma once
// The image as a continuous field: trilinear interpolation between voxel centres (the field
// whose level set CGAL's mesher meshes), and the points where that field crosses an iso value
// on the grid's edges, which lie exactly on its isosurface (along an edge the field is linear).
// Positions here are in the grid's own frame (mm from voxel (0, 0, 0) along the i, j, k axes:
// index times spacing); VolumeImage::position maps them into patient space.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "incise/imaging/volume_image.hpp"

namespace incise::imaging {

struct TrilinearSample {
  double value = 0.0;
  Vec3 gradient = Vec3::Zero();  ///< value per mm, grid frame (the cell's own, one-sided at faces)
};

/// The trilinear field at `grid_mm` (clamped to the box of the voxel centres). Pure.
[[nodiscard]] TrilinearSample sample_trilinear(const VolumeImage& image, const Vec3& grid_mm);

/// Moves `grid_mm` onto the isosurface along the field's gradient (Newton's method on the
/// value); returns false when the gradient vanishes or it does not settle within `iterations`.
[[nodiscard]] bool project_to_isosurface(const VolumeImage& image, double iso, Vec3& grid_mm,
                                         int iterations = 20);

struct IsoCrossings {
  std::vector<Vec3> points;  ///< mm, grid frame: a sample of the crossings
  std::size_t total = 0;     ///< crossings on the whole grid
};

/// Where the field crosses `iso` on the edges between neighbouring voxel centres: about
/// `wanted` of them (every one when there are fewer), chosen by a hash of the edge so the
/// choice is uniform over the surface's crossings and repeats for a `seed`. Parallel.
[[nodiscard]] IsoCrossings iso_crossings(const VolumeImage& image, double iso, std::size_t wanted,
                                         std::uint64_t seed = 0);

}  // namespace incise::imaging
