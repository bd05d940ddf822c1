#include "incise/imaging/volume_image.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "incise/core/error.hpp"

namespace incise::imaging {

std::array<float, 2> value_range(const VolumeImage& image) {
  if (image.values.empty()) {
    return {0.0F, 0.0F};
  }
  const auto [low, high] = std::minmax_element(image.values.begin(), image.values.end());
  return {*low, *high};
}

void check_volume(const VolumeImage& image, const std::string& what) {
  if (image.voxel_count() == 0 || image.values.size() != image.voxel_count()) {
    throw InputError(what, 0,
                     fmt::format("the volume holds {} values for {} x {} x {} voxels",
                                 image.values.size(), image.size[0], image.size[1], image.size[2]));
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (!(image.spacing[axis] > 0.0) || !std::isfinite(image.spacing[axis])) {
      throw InputError(what, 0,
                       fmt::format("voxel spacing {} along axis {} is not a positive length",
                                   image.spacing[axis], axis));
    }
  }
  if (!image.origin.allFinite()) {
    throw InputError(what, 0, "the volume's origin is not finite");
  }
  const double orthonormal_error =
      (image.direction.transpose() * image.direction - Eigen::Matrix3d::Identity()).norm();
  if (!(orthonormal_error < 1e-3)) {
    throw InputError(what, 0, "the volume's direction cosines are not orthonormal");
  }
  const auto bad = std::find_if(image.values.begin(), image.values.end(),
                                [](float v) { return !std::isfinite(v); });
  if (bad != image.values.end()) {
    const auto index = static_cast<std::size_t>(bad - image.values.begin());
    const std::size_t plane = image.size[0] * image.size[1];
    throw InputError(
        what, 0,
        fmt::format("voxel ({}, {}, {}) holds a non-finite value", index % image.size[0],
                    (index % plane) / image.size[0], index / plane));
  }
}

}  // namespace incise::imaging
