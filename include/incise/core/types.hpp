#pragma once
// Basic numeric types shared by every incise module. Lengths are metres (m) unless a
// file format says otherwise; incise never rescales what it reads.

#include <Eigen/Dense>
#include <array>
#include <cstdint>

namespace incise {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

using VertexId = std::int32_t;
using TetId = std::int32_t;
using EdgeId = std::int32_t;

/// Four vertex ids of a tetrahedron; positively oriented means
/// det[x1 - x0, x2 - x0, x3 - x0] > 0.
using Tet = std::array<VertexId, 4>;
/// Three vertex ids of a triangle, counter-clockwise seen from outside.
using Triangle = std::array<VertexId, 3>;

inline constexpr std::int32_t kInvalidId = -1;

/// The matrix of the cross product with v: cross_matrix(v) * w == v.cross(w).
[[nodiscard]] inline Mat3 cross_matrix(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

}  // namespace incise
