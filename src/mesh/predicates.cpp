#include "incise/mesh/predicates.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>
#include <CGAL/squared_distance_3.h>

#include <algorithm>
#include <array>
#include <limits>
#include <optional>

#include "incise/mesh/tet_mesh.hpp"

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

bool segments_intersect(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b) {
  if (p == q && a == b) {
    return p == a;
  }
  if (p == q) {
    return Kernel::Segment_3(to_cgal(a), to_cgal(b)).has_on(to_cgal(p));
  }
  if (a == b) {
    return Kernel::Segment_3(to_cgal(p), to_cgal(q)).has_on(to_cgal(a));
  }
  return CGAL::do_intersect(Kernel::Segment_3(to_cgal(p), to_cgal(q)),
                            Kernel::Segment_3(to_cgal(a), to_cgal(b)));
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

namespace {

/// Whether `axis` separates the points `first` from `second` by more than `slack` (m): a
/// conservative separating-axis test.
template <std::size_t N, std::size_t M>
bool separated_along(const Vec3& axis, const std::array<Vec3, N>& first,
                     const std::array<Vec3, M>& second, double slack) {
  double low1 = std::numeric_limits<double>::infinity();
  double high1 = -low1;
  double low2 = low1;
  double high2 = -low1;
  for (const Vec3& x : first) {
    low1 = std::min(low1, axis.dot(x));
    high1 = std::max(high1, axis.dot(x));
  }
  for (const Vec3& x : second) {
    low2 = std::min(low2, axis.dot(x));
    high2 = std::max(high2, axis.dot(x));
  }
  return low1 > high2 + slack || low2 > high1 + slack;
}

}  // namespace

namespace {

/// The orientation of three points of a plane seen from `eye`, a point off it: +1, -1 or 0
/// (exact, and the same sense for every triple of the plane).
int turn_in_plane(const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& eye) {
  const Sign sign = orient3d(p, q, r, eye);
  return sign == Sign::kPositive ? 1 : (sign == Sign::kNegative ? -1 : 0);
}

/// Whether a triangle and the convex hull of `part` (a point, a segment or a triangle that is
/// not flat), all in one plane with `eye` off it, are apart, decided exactly: two convex sets
/// in a plane are apart iff an edge of one has the other strictly outside it (separating
/// axes; a segment's edge is the segment itself, with either side outside).
bool apart_in_plane(const std::array<Vec3, 3>& triangle, std::span<const Vec3> part,
                    const Vec3& eye) {
  const int sense = turn_in_plane(triangle[0], triangle[1], triangle[2], eye);
  for (std::size_t e = 0; e < 3; ++e) {
    const bool all_outside = std::all_of(part.begin(), part.end(), [&](const Vec3& x) {
      return turn_in_plane(triangle[e], triangle[(e + 1) % 3], x, eye) * sense < 0;
    });
    if (all_outside) {
      return true;
    }
  }
  if (part.size() < 2) {
    return false;
  }
  const int part_sense = part.size() == 3 ? turn_in_plane(part[0], part[1], part[2], eye) : 0;
  for (std::size_t e = 0; e < (part.size() == 3 ? 3U : 1U); ++e) {
    int positive = 0;
    int negative = 0;
    for (const Vec3& corner : triangle) {
      const int side = turn_in_plane(part[e], part[(e + 1) % part.size()], corner, eye);
      positive += side > 0 ? 1 : 0;
      negative += side < 0 ? 1 : 0;
    }
    const bool outside = part.size() == 3 ? (part_sense > 0 ? negative == 3 : positive == 3)
                                          : (negative == 3 || positive == 3);
    if (outside) {
      return true;
    }
  }
  return false;
}

/// For a tetrahedron on one closed side of the plane of triangle (a, b, c) with the corners
/// marked on_plane in it: whether the triangle meets the tetrahedron's part in the plane (a
/// corner, an edge or a face), decided exactly; nothing when the tetrahedron is flat.
std::optional<bool> touching_in_plane(const Vec3& a, const Vec3& b, const Vec3& c,
                                      const std::array<Vec3, 4>& corners,
                                      const std::array<bool, 4>& on_plane, const Vec3& eye) {
  std::array<Vec3, 4> touching;
  std::size_t count = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    if (on_plane[k]) {
      touching[count++] = corners[k];
    }
  }
  if (count == 0) {
    return false;
  }
  if (count == 4 || orient3d(corners[0], corners[1], corners[2], corners[3]) == Sign::kZero) {
    return std::nullopt;  // a flat tetrahedron: the general test's answer
  }
  return !apart_in_plane({a, b, c}, std::span<const Vec3>(touching.data(), count), eye);
}

}  // namespace

bool triangle_intersects_tet(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& p0,
                             const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  // The triangle's plane and the tetrahedron's face planes first (the axes that separate a
  // swept blade triangle from most tetrahedra in its box); only what they cannot separate by
  // more than round-off reaches CGAL's exact test, the costly part of collision detection.
  {
    const std::array<Vec3, 3> triangle{a, b, c};
    const std::array<Vec3, 4> corners{p0, p1, p2, p3};
    double scale = 0.0;
    for (const Vec3& x : triangle) {
      scale = std::max(scale, x.cwiseAbs().maxCoeff());
    }
    for (const Vec3& x : corners) {
      scale = std::max(scale, x.cwiseAbs().maxCoeff());
    }
    const double slack = 1e-9 * scale;
    const Vec3 normal = (b - a).cross(c - a);
    if (normal.squaredNorm() > 0.0 &&
        separated_along(normal.normalized(), triangle, corners, slack)) {
      return false;
    }
    for (const auto& face : tet_local::kFaces) {
      const Vec3 face_normal =
          (corners[face[1]] - corners[face[0]]).cross(corners[face[2]] - corners[face[0]]);
      if (face_normal.squaredNorm() > 0.0 &&
          separated_along(face_normal.normalized(), triangle, corners, slack)) {
        return false;
      }
    }
  }
  // A tetrahedron on one side of the triangle's plane, touching it (a blade in a plane of mesh
  // faces, as when it enters along grid vertices): they meet only in that plane, which exact
  // orientations decide in 2-D. CGAL's general test spent most of a cut's collision time on
  // these (its interval filter gives up on the faces' collinear projections, throws, and
  // recomputes in multiprecision); there are more of them the finer the mesh.
  const std::array<Vec3, 4> corners{p0, p1, p2, p3};
  int above = 0;
  int below = 0;
  std::array<bool, 4> on_plane{};
  std::size_t off_plane = 0;  // a corner off the plane: the side the 2-D orientations look from
  for (std::size_t k = 0; k < 4; ++k) {
    const Sign side = orient3d(a, b, c, corners[k]);
    on_plane[k] = side == Sign::kZero;
    above += side == Sign::kPositive ? 1 : 0;
    below += side == Sign::kNegative ? 1 : 0;
    off_plane = side == Sign::kZero ? off_plane : k;
  }
  if (above == 0 && below == 0) {
    return false;  // the triangle is degenerate, or the tetrahedron flat in its plane
  }
  if (above == 0 || below == 0) {
    const auto touched = touching_in_plane(a, b, c, corners, on_plane, corners[off_plane]);
    if (touched.has_value()) {
      return *touched;
    }
  }
  const Kernel::Tetrahedron_3 tet(to_cgal(p0), to_cgal(p1), to_cgal(p2), to_cgal(p3));
  const Kernel::Triangle_3 triangle(to_cgal(a), to_cgal(b), to_cgal(c));
  if (tet.is_degenerate() || triangle.is_degenerate()) {
    return false;
  }
  return CGAL::do_intersect(triangle, tet);
}

namespace {

/// A cheap, conservative filter before the exact segment-tetrahedron test: false only when an
/// axis (the segment's direction or two perpendiculars) separates them by more than round-off.
/// Most tetrahedra near a long segment fail it, and CGAL's exact test is the costly part.
bool segment_may_meet_tet(const Vec3& p, const Vec3& q, const std::array<Vec3, 4>& tet) {
  // Relative to p, so the projections keep their precision far from the origin.
  const Vec3 d = q - p;
  const double length = d.norm();
  const Vec3 axis = d / length;
  const Vec3 u = axis.unitOrthogonal();
  std::array<Vec3, 4> corners;
  double scale = length;
  for (std::size_t k = 0; k < 4; ++k) {
    corners[k] = tet[k] - p;
    scale = std::max(scale, corners[k].cwiseAbs().maxCoeff());
  }
  const double slack = 1e-9 * scale;
  const std::array<Vec3, 2> segment{Vec3::Zero(), d};
  for (const Vec3& direction : {axis, u, axis.cross(u)}) {
    if (separated_along(direction, segment, corners, slack)) {
      return false;
    }
  }
  return true;
}

/// The segment clipped by the tetrahedron's four half-spaces in floating point: +1 when it
/// clearly meets the tetrahedron, 0 when it clearly misses, -1 when round-off could decide
/// (it grazes a face, edge or vertex): only then does the exact test run.
int clip_segment_by_tet(const Vec3& p, const Vec3& q, const std::array<Vec3, 4>& tet) {
  constexpr double kMargin = 1e-8;    // of the segment's parameter
  constexpr double kParallel = 1e-6;  // |rate| below this fraction: as good as parallel
  const Vec3 d = q - p;
  const double length = d.norm();
  double low = 0.0;
  double high = 1.0;
  bool unsure = false;
  for (int f = 0; f < 4; ++f) {
    const auto& face = tet_local::kFaces[f];
    const Vec3& a = tet[face[0]];
    Vec3 inward = (tet[face[1]] - a).cross(tet[face[2]] - a);
    const double size = inward.norm();
    if (size == 0.0) {
      return -1;
    }
    if (inward.dot(tet[f] - a) < 0.0) {
      inward = -inward;
    }
    const double at_p = inward.dot(p - a);
    const double rate = inward.dot(d);
    const double reach = size * (length + (p - a).norm());  // scale of at_p and rate
    if (std::abs(rate) <= kParallel * size * length) {
      if (at_p < -kMargin * reach) {
        return 0;  // parallel and outside
      }
      unsure = unsure || at_p <= kMargin * reach;
      continue;
    }
    const double s = -at_p / rate;
    if (rate > 0.0) {
      low = std::max(low, s);
    } else {
      high = std::min(high, s);
    }
  }
  if (low > high + kMargin) {
    return 0;
  }
  return !unsure && high > low + kMargin ? 1 : -1;
}

/// A segment in the plane of one of the tetrahedron's faces (a blade along a plane of mesh
/// faces): the tetrahedron lies on one side of that plane, so the segment meets it iff it
/// meets that face, decided exactly in 2-D (orientations seen from the opposite corner; apart
/// iff an edge of the face has both ends strictly outside, or the segment's line has the whole
/// face strictly on one side). Nothing when the segment is in no face's plane or the
/// tetrahedron is flat. CGAL's general test spent most of the blade line's time here, its
/// interval filter giving up on collinear projections and recomputing in multiprecision.
std::optional<bool> segment_in_face_plane(const Vec3& p, const Vec3& q,
                                          const std::array<Vec3, 4>& tet) {
  if (orient3d(tet[0], tet[1], tet[2], tet[3]) == Sign::kZero) {
    return std::nullopt;
  }
  for (std::size_t f = 0; f < 4; ++f) {
    const auto& face = tet_local::kFaces[f];
    const Vec3& a = tet[face[0]];
    const Vec3& b = tet[face[1]];
    const Vec3& c = tet[face[2]];
    if (orient3d(a, b, c, p) != Sign::kZero || orient3d(a, b, c, q) != Sign::kZero) {
      continue;
    }
    const std::array<Vec3, 2> segment{p, q};
    return !apart_in_plane({a, b, c}, segment, tet[f]);  // seen from the opposite corner
  }
  return std::nullopt;
}

}  // namespace

bool segment_intersects_tet(const Vec3& p, const Vec3& q, const Vec3& p0, const Vec3& p1,
                            const Vec3& p2, const Vec3& p3) {
  // Boxes apart along an axis: exact (comparisons of the inputs, no arithmetic), and the
  // cheapest way out for most tetrahedra a grid returns around a long segment.
  const Vec3 tet_low = p0.cwiseMin(p1).cwiseMin(p2).cwiseMin(p3);
  const Vec3 tet_high = p0.cwiseMax(p1).cwiseMax(p2).cwiseMax(p3);
  if ((tet_low.array() > p.cwiseMax(q).array()).any() ||
      (tet_high.array() < p.cwiseMin(q).array()).any()) {
    return false;
  }
  if (p != q) {
    if (!segment_may_meet_tet(p, q, {p0, p1, p2, p3})) {
      return false;
    }
    const int clipped = clip_segment_by_tet(p, q, {p0, p1, p2, p3});
    if (clipped >= 0) {
      return clipped == 1;
    }
    const auto in_face_plane = segment_in_face_plane(p, q, {p0, p1, p2, p3});
    if (in_face_plane.has_value()) {
      return *in_face_plane;
    }
  }
  const Kernel::Tetrahedron_3 tet(to_cgal(p0), to_cgal(p1), to_cgal(p2), to_cgal(p3));
  if (tet.is_degenerate()) {
    return false;
  }
  if (p == q) {
    return !tet.has_on_unbounded_side(to_cgal(p));
  }
  return CGAL::do_intersect(Kernel::Segment_3(to_cgal(p), to_cgal(q)), tet);
}

namespace {

double squared_distance_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double length2 = ab.squaredNorm();
  const double t = length2 > 0.0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).squaredNorm();
}

/// Where the point of triangle (a, b, c) nearest p lies, by Ericson's Voronoi-region tests
/// (Real-Time Collision Detection, 5.1.5): a corner, an edge, the face, or nowhere in
/// particular for collinear corners. For an edge, `s` places the point along it (ab: a + s ab,
/// ac: a + s ac, bc: b + s (c - b)); for the face, a + s ab + t ac.
struct NearestOnTriangle {
  enum class Region { kA, kB, kC, kAB, kAC, kBC, kFace, kDegenerate };
  Region region = Region::kFace;
  double s = 0.0;
  double t = 0.0;
};

NearestOnTriangle nearest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  using Region = NearestOnTriangle::Region;
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    return {Region::kA};
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    return {Region::kB};
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    return {Region::kC};
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    return {Region::kAB, d1 / (d1 - d3)};
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    return {Region::kAC, d2 / (d2 - d6)};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return {Region::kBC, (d4 - d3) / ((d4 - d3) + (d5 - d6))};
  }
  const double denominator = va + vb + vc;
  if (!(denominator > 1e-14 * ab.squaredNorm() * ac.squaredNorm())) {
    return {Region::kDegenerate};
  }
  return {Region::kFace, vb / denominator, vc / denominator};
}

}  // namespace

// Ericson's closest point in plain double: the cutter asks millions of these per second
// against tolerances of a fraction of an edge, where CGAL's version, exact in its degeneracy
// test, fell back to multi-precision arithmetic on the thin triangles a cut accumulates and
// dominated the cost of a pose.
double squared_distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  using Region = NearestOnTriangle::Region;
  switch (nearest_on_triangle(p, a, b, c).region) {
    case Region::kA:
      return (p - a).squaredNorm();
    case Region::kB:
      return (p - b).squaredNorm();
    case Region::kC:
      return (p - c).squaredNorm();
    case Region::kAB:
      return squared_distance_to_segment(p, a, b);
    case Region::kAC:
      return squared_distance_to_segment(p, a, c);
    case Region::kBC:
      return squared_distance_to_segment(p, b, c);
    case Region::kDegenerate:
      // Collinear corners: the nearest of the three edges.
      return std::min({squared_distance_to_segment(p, a, b), squared_distance_to_segment(p, b, c),
                       squared_distance_to_segment(p, c, a)});
    case Region::kFace:
      break;
  }
  // Inside the face: the distance to its plane, free of the cancellation in a + v ab + w ac - p.
  const Vec3 normal = (b - a).cross(c - a);
  const double height = normal.dot(p - a);
  return height * height / normal.squaredNorm();
}

std::array<double, 3> closest_point_barycentric(const Vec3& p, const Vec3& a, const Vec3& b,
                                                const Vec3& c) {
  using Region = NearestOnTriangle::Region;
  const NearestOnTriangle nearest = nearest_on_triangle(p, a, b, c);
  switch (nearest.region) {
    case Region::kA:
      return {1.0, 0.0, 0.0};
    case Region::kB:
      return {0.0, 1.0, 0.0};
    case Region::kC:
      return {0.0, 0.0, 1.0};
    case Region::kAB:
      return {1.0 - nearest.s, nearest.s, 0.0};
    case Region::kAC:
      return {1.0 - nearest.s, 0.0, nearest.s};
    case Region::kBC:
      return {0.0, 1.0 - nearest.s, nearest.s};
    case Region::kFace:
      return {1.0 - nearest.s - nearest.t, nearest.s, nearest.t};
    case Region::kDegenerate:
      break;
  }
  // Collinear corners: the nearest point of the nearest edge.
  const auto on_edge = [&](const Vec3& from, const Vec3& to) {
    const Vec3 along = to - from;
    const double length2 = along.squaredNorm();
    return length2 > 0.0 ? std::clamp((p - from).dot(along) / length2, 0.0, 1.0) : 0.0;
  };
  const std::array<double, 3> ab{1.0 - on_edge(a, b), on_edge(a, b), 0.0};
  const std::array<double, 3> bc{0.0, 1.0 - on_edge(b, c), on_edge(b, c)};
  const std::array<double, 3> ca{on_edge(c, a), 0.0, 1.0 - on_edge(c, a)};
  const auto distance = [&](const std::array<double, 3>& w) {
    return (w[0] * a + w[1] * b + w[2] * c - p).squaredNorm();
  };
  std::array<double, 3> best = ab;
  for (const auto& candidate : {bc, ca}) {
    if (distance(candidate) < distance(best)) {
      best = candidate;
    }
  }
  return best;
}

TetLocation locate_in_tet(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                          const Vec3& d) {
  // Outside the box is outside (the comparisons are exact), and far cheaper to find.
  const Vec3 low = a.cwiseMin(b).cwiseMin(c).cwiseMin(d);
  const Vec3 high = a.cwiseMax(b).cwiseMax(c).cwiseMax(d);
  if ((p.array() < low.array()).any() || (p.array() > high.array()).any()) {
    return TetLocation::kOutside;
  }
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
