#include "incise/mesh/predicates.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>
#include <CGAL/squared_distance_3.h>

#include <limits>

namespace incise {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;

Point to_cgal(const Vec3& p) {
  return {p.x(), p.y(), p.z()};
}

Sign to_sign(CGAL::Sign sign) {
  switch (sign) {
    case CGAL::NEGATIVE:
      return Sign::kNegative;
    case CGAL::POSITIVE:
      return Sign::kPositive;
    default:
      return Sign::kZero;
  }
}

}  // namespace

Sign orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  // CGAL::orientation(p, q, r, s) is the sign of det[q - p, r - p, s - p].
  return to_sign(CGAL::orientation(to_cgal(a), to_cgal(b), to_cgal(c), to_cgal(d)));
}

bool segment_intersects_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b,
                                 const Vec3& c) {
  const Kernel::Triangle_3 triangle(to_cgal(a), to_cgal(b), to_cgal(c));
  if (p == q) {
    return triangle.has_on(to_cgal(p));
  }
  if (triangle.is_degenerate()) {
    return false;
  }
  return CGAL::do_intersect(Kernel::Segment_3(to_cgal(p), to_cgal(q)), triangle);
}

bool triangles_intersect(const Vec3& a0, const Vec3& b0, const Vec3& c0, const Vec3& a1,
                         const Vec3& b1, const Vec3& c1) {
  const Kernel::Triangle_3 first(to_cgal(a0), to_cgal(b0), to_cgal(c0));
  const Kernel::Triangle_3 second(to_cgal(a1), to_cgal(b1), to_cgal(c1));
  if (first.is_degenerate() || second.is_degenerate()) {
    return false;
  }
  return CGAL::do_intersect(first, second);
}

bool triangle_intersects_tet(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& p0,
                             const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  const Kernel::Tetrahedron_3 tet(to_cgal(p0), to_cgal(p1), to_cgal(p2), to_cgal(p3));
  const Kernel::Triangle_3 triangle(to_cgal(a), to_cgal(b), to_cgal(c));
  if (tet.is_degenerate() || triangle.is_degenerate()) {
    return false;
  }
  return CGAL::do_intersect(triangle, tet);
}

bool segment_intersects_tet(const Vec3& p, const Vec3& q, const Vec3& p0, const Vec3& p1,
                            const Vec3& p2, const Vec3& p3) {
  const Kernel::Tetrahedron_3 tet(to_cgal(p0), to_cgal(p1), to_cgal(p2), to_cgal(p3));
  if (tet.is_degenerate()) {
    return false;
  }
  if (p == q) {
    return !tet.has_on_unbounded_side(to_cgal(p));
  }
  return CGAL::do_intersect(Kernel::Segment_3(to_cgal(p), to_cgal(q)), tet);
}

double squared_distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Kernel::Triangle_3 triangle(to_cgal(a), to_cgal(b), to_cgal(c));
  if (triangle.is_degenerate()) {
    // Fall back to the closest of the three segments.
    double best = std::numeric_limits<double>::infinity();
    for (const auto& [u, w] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
      best = std::min(best, CGAL::to_double(CGAL::squared_distance(
                                to_cgal(p), Kernel::Segment_3(to_cgal(u), to_cgal(w)))));
    }
    return best;
  }
  return CGAL::to_double(CGAL::squared_distance(to_cgal(p), triangle));
}

TetLocation locate_in_tet(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                          const Vec3& d) {
  // p is inside when it is on the inner side of all four faces (each replacing one vertex).
  const Sign signs[4] = {orient3d(p, b, c, d), orient3d(a, p, c, d), orient3d(a, b, p, d),
                         orient3d(a, b, c, p)};
  bool on_boundary = false;
  for (Sign sign : signs) {
    if (sign == Sign::kNegative) {
      return TetLocation::kOutside;
    }
    on_boundary = on_boundary || sign == Sign::kZero;
  }
  return on_boundary ? TetLocation::kBoundary : TetLocation::kInside;
}

}  // namespace incise
