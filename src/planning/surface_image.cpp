#include "incise/planning/surface_image.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/mesh/predicates.hpp"

namespace incise::planning {

imaging::VolumeImage signed_distance_image(const SurfaceMesh& surface, double spacing) {
  if (surface.triangles.empty() || !(spacing > 0.0)) {
    throw InputError("signed_distance_image needs triangles and a positive spacing");
  }
  Vec3 low = Vec3::Constant(std::numeric_limits<double>::max());
  Vec3 high = Vec3::Constant(std::numeric_limits<double>::lowest());
  for (const Vec3& p : surface.points) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  // Three voxels and an irrational part of one: the grid's planes then pass through no plane
  // of the input's corners (a scan's surface has its border and many corners in the planes of
  // its own voxels; a row of the grid in such a plane met a flat hole fill edge-on and the
  // parity below went wrong by a rounding of the input).
  constexpr double kMargin = 3.0 + 0.3819660112501051;  // voxels (2 minus the golden ratio)
  imaging::VolumeImage image;
  image.spacing = Vec3::Constant(spacing);
  image.origin = low - Vec3::Constant(kMargin * spacing);
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const auto a = static_cast<Eigen::Index>(axis);
    image.size[axis] =
        static_cast<std::size_t>(std::ceil((high[a] - low[a]) / spacing + 2.0 * kMargin)) + 1;
  }
  const std::size_t nx = image.size[0];
  const std::size_t ny = image.size[1];
  const std::size_t nz = image.size[2];
  const auto band = static_cast<float>(2.0 * spacing);
  image.values.assign(nx * ny * nz, -band);
  image.description = "signed distance to a surface (mm, positive inside)";

  // Triangles by the slices their box (grown by the band) spans.
  const auto index_of = [&](double coordinate, std::size_t axis) {
    return (coordinate - image.origin[static_cast<Eigen::Index>(axis)]) / spacing;
  };
  std::vector<std::vector<std::size_t>> slice_triangles(nz);
  std::vector<std::array<Vec3, 2>> boxes(surface.triangles.size());
  for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
    const Triangle& tri = surface.triangles[t];
    Vec3 box_low = surface.points[static_cast<std::size_t>(tri[0])];
    Vec3 box_high = box_low;
    for (std::size_t c = 1; c < 3; ++c) {
      box_low = box_low.cwiseMin(surface.points[static_cast<std::size_t>(tri[c])]);
      box_high = box_high.cwiseMax(surface.points[static_cast<std::size_t>(tri[c])]);
    }
    boxes[t] = {box_low, box_high};
    const auto k0 =
        static_cast<std::size_t>(std::max(0.0, std::ceil(index_of(box_low.z(), 2) - 2.0)));
    const auto k1 =
        std::min(nz - 1, static_cast<std::size_t>(std::floor(index_of(box_high.z(), 2) + 2.0)));
    for (std::size_t k = k0; k <= k1; ++k) {
      slice_triangles[k].push_back(t);
    }
  }

  tbb::parallel_for(std::size_t{0}, nz, [&](std::size_t k) {
    const double z = image.origin.z() + static_cast<double>(k) * spacing;
    float* slice = &image.values[nx * ny * k];
    // The sign: along each row (+x), the crossings of the triangles whose yz-box holds the
    // row, by parity. The row sits a hair off the grid so it meets no edge or corner exactly.
    std::vector<std::vector<std::size_t>> row_triangles(ny);
    for (const std::size_t t : slice_triangles[k]) {
      const auto& [box_low, box_high] = boxes[t];
      if (box_low.z() > z || box_high.z() < z) {
        continue;
      }
      const auto j0 = static_cast<std::size_t>(std::max(0.0, std::ceil(index_of(box_low.y(), 1))));
      const auto j1 = std::min(
          ny - 1, static_cast<std::size_t>(std::max(0.0, std::floor(index_of(box_high.y(), 1)))));
      for (std::size_t j = j0; j <= j1; ++j) {
        row_triangles[j].push_back(t);
      }
    }
    std::vector<double> crossings;
    for (std::size_t j = 0; j < ny; ++j) {
      const double y = image.origin.y() + static_cast<double>(j) * spacing + 1e-7 * spacing;
      const double zr = z + 1.3e-7 * spacing;
      crossings.clear();
      for (const std::size_t t : row_triangles[j]) {
        const Triangle& tri = surface.triangles[t];
        const Vec3& a = surface.points[static_cast<std::size_t>(tri[0])];
        const Vec3& b = surface.points[static_cast<std::size_t>(tri[1])];
        const Vec3& c = surface.points[static_cast<std::size_t>(tri[2])];
        // Barycentric coordinates of (y, zr) in the triangle projected on the yz-plane.
        const double d = (b.y() - a.y()) * (c.z() - a.z()) - (c.y() - a.y()) * (b.z() - a.z());
        if (d == 0.0) {
          continue;
        }
        const double u = ((y - a.y()) * (c.z() - a.z()) - (c.y() - a.y()) * (zr - a.z())) / d;
        const double v = ((b.y() - a.y()) * (zr - a.z()) - (y - a.y()) * (b.z() - a.z())) / d;
        if (u < 0.0 || v < 0.0 || u + v > 1.0) {
          continue;
        }
        crossings.push_back(a.x() + u * (b.x() - a.x()) + v * (c.x() - a.x()));
      }
      std::sort(crossings.begin(), crossings.end());
      float* row = slice + nx * j;
      for (std::size_t c = 0; c + 1 < crossings.size(); c += 2) {
        const double i0 = std::ceil(index_of(crossings[c], 0));
        const double i1 = std::floor(index_of(crossings[c + 1], 0));
        for (double i = std::max(i0, 0.0); i <= i1 && i < static_cast<double>(nx); i += 1.0) {
          row[static_cast<std::size_t>(i)] = band;
        }
      }
    }
    // The distance, within the band of each triangle.
    for (const std::size_t t : slice_triangles[k]) {
      const Triangle& tri = surface.triangles[t];
      const Vec3& a = surface.points[static_cast<std::size_t>(tri[0])];
      const Vec3& b = surface.points[static_cast<std::size_t>(tri[1])];
      const Vec3& c = surface.points[static_cast<std::size_t>(tri[2])];
      const auto& [box_low, box_high] = boxes[t];
      const auto i0 =
          static_cast<std::size_t>(std::max(0.0, std::ceil(index_of(box_low.x(), 0) - 2.0)));
      const auto i1 =
          std::min(nx - 1, static_cast<std::size_t>(std::floor(index_of(box_high.x(), 0) + 2.0)));
      const auto j0 =
          static_cast<std::size_t>(std::max(0.0, std::ceil(index_of(box_low.y(), 1) - 2.0)));
      const auto j1 =
          std::min(ny - 1, static_cast<std::size_t>(std::floor(index_of(box_high.y(), 1) + 2.0)));
      for (std::size_t j = j0; j <= j1; ++j) {
        for (std::size_t i = i0; i <= i1; ++i) {
          const Vec3 p =
              image.origin + spacing * Vec3(static_cast<double>(i), static_cast<double>(j),
                                            static_cast<double>(k));
          const auto distance =
              static_cast<float>(std::sqrt(squared_distance_to_triangle(p, a, b, c)));
          float& value = slice[i + nx * j];
          if (distance < std::abs(value)) {
            value = std::copysign(distance, value);
          }
        }
      }
    }
  });
  return image;
}

}  // namespace incise::planning
