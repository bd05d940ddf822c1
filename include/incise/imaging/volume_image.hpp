#pragma once
// A scalar volume as CT scanners and MetaImage files give it: voxel values on a regular grid
// placed in patient space by an origin, a spacing and a direction. Lengths are millimetres, as
// in DICOM and MetaImage; values are whatever the file holds (Hounsfield units for a DICOM CT,
// its rescale slope and intercept applied).

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "incise/core/types.hpp"

namespace incise::imaging {

/// A scalar volume (a CT) in patient space, as read from MetaImage or DICOM.
struct VolumeImage {
  std::array<std::size_t, 3> size{0, 0, 0};  ///< voxels along the i, j and k axes
  Vec3 spacing = Vec3::Ones();               ///< mm between voxel centres along i, j, k
  Vec3 origin = Vec3::Zero();                ///< mm: the centre of voxel (0, 0, 0)
  /// Columns: the directions of the i, j and k axes in patient space (unit, orthogonal).
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  std::vector<float> values;  ///< i fastest, then j, then k
  std::string description;    ///< what was read: format and voxel type, for reports

  /// Voxels in all.
  [[nodiscard]] std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
  /// The value of voxel (i, j, k).
  [[nodiscard]] float at(std::size_t i, std::size_t j, std::size_t k) const {
    return values[i + size[0] * (j + size[1] * k)];
  }
  /// mm: where the point of (fractional) voxel index (i, j, k) lies in patient space.
  [[nodiscard]] Vec3 position(const Vec3& index) const {
    return origin + direction * spacing.cwiseProduct(index);
  }
};

/// The smallest and largest voxel value.
[[nodiscard]] std::array<float, 2> value_range(const VolumeImage& image);

/// Checks the grid's consistency (sizes against the values, positive finite spacing, finite
/// values, an orthonormal direction); throws InputError naming `what` and the fault.
void check_volume(const VolumeImage& image, const std::string& what);

}  // namespace incise::imaging
