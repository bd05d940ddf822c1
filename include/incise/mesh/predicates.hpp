#pragma once
// Exact geometric predicates. Signs come from CGAL's filtered exact kernel (interval
// arithmetic with an exact fallback), so cutting decisions never depend on round-off.
// Inputs must be finite.

#include <array>

#include "incise/core/types.hpp"

namespace incise {

enum class Sign : int { kNegative = -1, kZero = 0, kPositive = 1 };

/// Exact sign of det[b - a, c - a, d - a]: positive when (a, b, c, d) is a positively
/// oriented tetrahedron, zero when the four points are coplanar.
[[nodiscard]] Sign orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Exact test: does the closed segment [p, q] meet the closed triangle (a, b, c)?
[[nodiscard]] bool segment_intersects_triangle(const Vec3& p, const Vec3& q, const Vec3& a,
                                               const Vec3& b, const Vec3& c);

/// Exact test: do the closed segments [p, q] and [a, b] meet? (A degenerate segment is its
/// point.)
[[nodiscard]] bool segments_intersect(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b);

/// Exact test: do two closed triangles meet?
[[nodiscard]] bool triangles_intersect(const Vec3& a0, const Vec3& b0, const Vec3& c0,
                                       const Vec3& a1, const Vec3& b1, const Vec3& c1);

/// Exact test: does the closed triangle (a, b, c) meet the closed tetrahedron (p0..p3)?
[[nodiscard]] bool triangle_intersects_tet(const Vec3& a, const Vec3& b, const Vec3& c,
                                           const Vec3& p0, const Vec3& p1, const Vec3& p2,
                                           const Vec3& p3);

/// Exact test: does the closed segment [p, q] meet the closed tetrahedron (p0..p3)?
[[nodiscard]] bool segment_intersects_tet(const Vec3& p, const Vec3& q, const Vec3& p0,
                                          const Vec3& p1, const Vec3& p2, const Vec3& p3);

/// Squared distance (m^2) from a point to a closed triangle (floating point).
[[nodiscard]] double squared_distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b,
                                                  const Vec3& c);
/// Barycentric coordinates of the triangle's point nearest p (floating point, the same region
/// tests as squared_distance_to_triangle).
[[nodiscard]] std::array<double, 3> closest_point_barycentric(const Vec3& p, const Vec3& a,
                                                              const Vec3& b, const Vec3& c);

/// Where a point lies with respect to a positively oriented tetrahedron.
enum class TetLocation { kOutside, kBoundary, kInside };

/// Exact location of p in the closed tetrahedron (a, b, c, d), which must be positive.
[[nodiscard]] TetLocation locate_in_tet(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                        const Vec3& d);

}  // namespace incise
