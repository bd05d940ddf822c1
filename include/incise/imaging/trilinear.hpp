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

/// The image's trilinear field at a point: its value and gradient.
struct TrilinearSample {
  double value = 0.0;            ///< in the image's units
  Vec3 gradient = Vec3::Zero();  ///< value per mm, grid frame (the cell's own, one-sided at faces)
};

/// The trilinear field at `grid_mm` (clamped to the box of the voxel centres). Pure.
[[nodiscard]] TrilinearSample sample_trilinear(const VolumeImage& image, const Vec3& grid_mm);

/// Moves `grid_mm` onto the isosurface along the field's gradient (Newton's method on the
/// value); returns false when the gradient vanishes or it does not settle within `iterations`.
[[nodiscard]] bool project_to_isosurface(const VolumeImage& image, double iso, Vec3& grid_mm,
                                         int iterations = 20);

/// Per voxel: 1 where the value is at most `iso` and the voxel reaches the scan's border
/// through such voxels (6-neighbours): the air around the body for the skin's iso value, the
/// soft tissue around the bones for the bone's. Voxels at most `iso` that are left 0 are
/// enclosed: airways, sinuses, the marrow inside a bone.
[[nodiscard]] std::vector<std::uint8_t> outside_of(const VolumeImage& image, double iso);

/// Per voxel: 1 where the value is above `iso` in a 6-connected region of fewer than
/// `least_voxels` such voxels: specks (of cancellous bone, of noise) too small for a surface
/// mesher of a coarser size to represent.
[[nodiscard]] std::vector<std::uint8_t> small_regions_above(const VolumeImage& image, double iso,
                                                            std::size_t least_voxels);

/// Points where the image crosses an iso value between voxel centres, sampled.
struct IsoCrossings {
  std::vector<Vec3> points;  ///< mm, grid frame: a sample of the crossings
  /// Per point, with an `outside` mask only: 1 when the crossing bounds an enclosed region
  /// (its voxel at most iso is not outside).
  std::vector<std::uint8_t> enclosed;
  /// Per point, with a `small_above` mask only: 1 when its voxel above iso is in a small region.
  std::vector<std::uint8_t> on_small_region;
  std::size_t total = 0;  ///< crossings on the whole grid
};

/// Where the field crosses `iso` on the edges between neighbouring voxel centres: about
/// `wanted` of them (every one when there are fewer), chosen by a hash of the edge so the
/// choice is uniform over the surface's crossings and repeats for a `seed`. Parallel. With
/// `outside` (outside_of's mask for the same iso), each point says whether it is enclosed; with
/// `small_above` (small_regions_above's), whether it bounds a small region.
[[nodiscard]] IsoCrossings iso_crossings(const VolumeImage& image, double iso, std::size_t wanted,
                                         std::uint64_t seed = 0,
                                         const std::vector<std::uint8_t>* outside = nullptr,
                                         const std::vector<std::uint8_t>* small_above = nullptr);

}  // namespace incise::imaging
