#pragma once
// Small geometric helpers shared by the parts of the subdivision cutter (rest corners and
// faces, areas, centroids, sides, quality floors). Internal to the cut module.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/mesh/validate.hpp"

namespace incise::cutter_detail {

/// How far (a fraction of its longest edge) a face's centroid may lie off a curved swept
/// surface when its corners lie on it.
constexpr double kSweptSurfaceBulge = 0.05;

inline double longest_edge(const std::array<Vec3, 3>& t) {
  return std::max({(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()});
}

/// The unit normal of a triangle.
inline Vec3 unit_normal(const std::array<Vec3, 3>& t) {
  return (t[1] - t[0]).cross(t[2] - t[0]).normalized();
}

/// The vertices of a tetrahedron's face, sorted: one key per face whichever tet it is seen from.
inline std::array<VertexId, 3> face_key(const Tet& tet, int local_face) {
  const auto& face = tet_local::kFaces[local_face];
  std::array<VertexId, 3> key{tet[face[0]], tet[face[1]], tet[face[2]]};
  std::sort(key.begin(), key.end());
  return key;
}

inline double longest_edge(const std::array<Vec3, 4>& corners) {
  double longest = 0.0;
  for (const auto& e : tet_local::kEdges) {
    longest = std::max(longest, (corners[e[0]] - corners[e[1]]).norm());
  }
  return longest;
}

/// A face's corners at rest, in tet_local::kFaces order.
inline std::array<Vec3, 3> rest_face(const TetMesh& mesh, TetId tet, int local_face) {
  const Tet& v = mesh.tet(tet);
  const auto& face = tet_local::kFaces[local_face];
  return {mesh.rest_position(v[face[0]]), mesh.rest_position(v[face[1]]),
          mesh.rest_position(v[face[2]])};
}

inline double area(const std::array<Vec3, 3>& t) {
  return 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
}

inline Vec3 centroid(const std::array<Vec3, 3>& corners) {
  return (corners[0] + corners[1] + corners[2]) / 3.0;
}

inline Vec3 centroid(const std::array<Vec3, 4>& corners) {
  return (corners[0] + corners[1] + corners[2] + corners[3]) / 4.0;
}

/// Which side (-1, +1) of the plane of `triangle` a point is on (+1 on the plane).
// Normalized volumes (1: regular). Blade-line vertices are optional (the crossings of the
// swept surface open the cut without them), so one that would thin the tetrahedra around it
// towards degenerate (1e-6) is left out: no child or slid tetrahedron goes below this floor
// unless it was there already, however many tiny steps the blade takes.
inline constexpr double kQualityFloor = 1e-4;

// A slide may also thin a tetrahedron by at most half per pose below 0.05.
inline double slide_floor(double before) {
  constexpr double kGood = 0.05;
  return std::max(std::min(kGood, 0.5 * before), std::min(before, kQualityFloor));
}

inline double quality(const std::array<Vec3, 4>& corners) {
  return normalized_volume(corners[0], corners[1], corners[2], corners[3]);
}

/// Whether tetrahedron `t` is positively oriented (exactly) with its corner `local` at `moved`
/// and its other corners where `position_of(vertex)` puts them (rest, cutter or simulation
/// positions).
template <typename PositionOf>
bool positive_with_corner_at(const TetMesh& mesh, TetId t, int local, const Vec3& moved,
                             const PositionOf& position_of) {
  const Tet& v = mesh.tet(t);
  std::array<Vec3, 4> p{position_of(v[0]), position_of(v[1]), position_of(v[2]), position_of(v[3])};
  p[static_cast<std::size_t>(local)] = moved;
  return orient3d(p[0], p[1], p[2], p[3]) == Sign::kPositive;
}

inline int side_of(const Vec3& point, const std::array<Vec3, 3>& triangle) {
  const Vec3 normal = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]);
  return normal.dot(point - triangle[0]) < 0.0 ? -1 : 1;
}

/// Distance (m) from a point to the nearest of some triangles (infinity when there are none).
inline double distance_to(const std::vector<std::array<Vec3, 3>>& triangles, const Vec3& point) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : triangles) {
    best = std::min(best, squared_distance_to_triangle(point, t[0], t[1], t[2]));
  }
  return std::sqrt(best);
}

inline void triangle_bounds(const std::array<Vec3, 3>& triangle, Vec3& low, Vec3& high) {
  low = triangle[0].cwiseMin(triangle[1]).cwiseMin(triangle[2]);
  high = triangle[0].cwiseMax(triangle[1]).cwiseMax(triangle[2]);
}

}  // namespace incise::cutter_detail
