#include "incise/mesh/predicates.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>

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
