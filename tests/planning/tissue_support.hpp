#pragma once
// What the planning tests share: icospheres (concentric skin and bone surfaces) and the free
// points of a tissue.

#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "incise/io/mesh_io.hpp"
#include "incise/planning/layered_tissue.hpp"

namespace incise::testing {

/// An icosphere of `levels` subdivisions (outward triangles), radius r (m), centre c.
inline SurfaceMesh sphere(double r, int levels, const Vec3& c = Vec3::Zero()) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  SurfaceMesh s;
  s.points = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
              {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  s.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> middle;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto found = middle.find(key);
      if (found != middle.end()) {
        return found->second;
      }
      s.points.push_back(
          0.5 * (s.points[static_cast<std::size_t>(a)] + s.points[static_cast<std::size_t>(b)]));
      return middle[key] = static_cast<int>(s.points.size()) - 1;
    };
    std::vector<Triangle> finer;
    for (const Triangle& tri : s.triangles) {
      const int ab = mid(tri[0], tri[1]);
      const int bc = mid(tri[1], tri[2]);
      const int ca = mid(tri[2], tri[0]);
      finer.push_back({tri[0], ab, ca});
      finer.push_back({tri[1], bc, ab});
      finer.push_back({tri[2], ca, bc});
      finer.push_back({ab, bc, ca});
    }
    s.triangles = finer;
  }
  for (Vec3& p : s.points) {
    p = c + r * p.normalized();
  }
  return s;
}

/// Soft points are free; bone and boundary points are held.
inline std::vector<char> free_points(const planning::LayeredTissue& tissue) {
  std::vector<char> free(tissue.point_count(), 0);
  for (std::size_t i = 0; i < free.size(); ++i) {
    free[i] = tissue.kind[i] == planning::PointKind::kSoft ? 1 : 0;
  }
  return free;
}

}  // namespace incise::testing
