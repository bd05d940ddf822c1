// Predicates, quality measures, boundary surface and components.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/quality.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

TEST(Predicates, OrientationConventionMatchesSignedVolume) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), d(0, 0, 1);
  EXPECT_GT(signed_volume(a, b, c, d), 0.0);
  EXPECT_EQ(orient3d(a, b, c, d), Sign::kPositive);
  EXPECT_EQ(orient3d(a, c, b, d), Sign::kNegative);
  EXPECT_EQ(orient3d(a, b, c, Vec3(0.3, 0.7, 0.0)), Sign::kZero);
}

TEST(Predicates, ExactWhereFloatingPointIsNot) {
  // Points on a line with coordinates that are not representable: naive determinants give
  // noise, the exact predicate says coplanar whenever the doubles truly are.
  const Vec3 a(0.1, 0.1, 0.1), b(0.2, 0.2, 0.2), c(0.3, 0.7, 0.4);
  const Vec3 d = a;  // exactly coincident
  EXPECT_EQ(orient3d(a, b, c, d), Sign::kZero);
  // Nearly degenerate but truly positive: 2^-60 off the plane z = 0.
  const Vec3 e(0.5, 0.25, std::ldexp(1.0, -60));
  EXPECT_EQ(orient3d(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), e), Sign::kPositive);
}

TEST(Predicates, SegmentTriangle) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_TRUE(segment_intersects_triangle(Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), a, b, c));
  EXPECT_FALSE(segment_intersects_triangle(Vec3(0.8, 0.8, -1), Vec3(0.8, 0.8, 1), a, b, c));
  // Through a vertex and along an edge (closed sets): intersect.
  EXPECT_TRUE(segment_intersects_triangle(Vec3(0, 0, -1), Vec3(0, 0, 1), a, b, c));
  EXPECT_TRUE(segment_intersects_triangle(Vec3(-1, 0, 0), Vec3(2, 0, 0), a, b, c));
  EXPECT_FALSE(segment_intersects_triangle(Vec3(0.2, 0.2, 0.1), Vec3(0.2, 0.2, 1), a, b, c));
  EXPECT_TRUE(triangles_intersect(a, b, c, Vec3(0.1, 0.1, -1), Vec3(0.1, 0.1, 1), Vec3(2, 2, 0.5)));
}

TEST(Predicates, DistanceToTriangleMatchesBruteForce) {
  // Against the minimum over a fine sampling of the triangle, for random points and triangles,
  // slivers and collinear (degenerate) ones included.
  std::mt19937 random(7);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  const auto random_point = [&] {
    return Vec3(coordinate(random), coordinate(random), coordinate(random));
  };
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 a = random_point();
    const Vec3 b = random_point();
    Vec3 c = random_point();
    if (trial % 3 == 1) {
      c = a + 0.37 * (b - a);  // collinear
    } else if (trial % 3 == 2) {
      c = a + 0.5 * (b - a) + 1e-9 * random_point();  // a sliver
    }
    const Vec3 p = random_point();
    double brute = std::numeric_limits<double>::infinity();
    const int steps = 200;
    for (int i = 0; i <= steps; ++i) {
      for (int j = 0; i + j <= steps; ++j) {
        const double u = double(i) / steps;
        const double v = double(j) / steps;
        brute = std::min(brute, (a + u * (b - a) + v * (c - a) - p).squaredNorm());
      }
    }
    const double fast = std::sqrt(incise::squared_distance_to_triangle(p, a, b, c));
    // The sampling is at most half a sample step (of the longest edge) off.
    const double step = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()}) / steps;
    EXPECT_LE(fast, std::sqrt(brute) + 1e-12) << "trial " << trial;
    EXPECT_GE(fast, std::sqrt(brute) - step) << "trial " << trial;
  }
}

/// A point in [-2, 2]^3: on the integer grid (touching cases are common), or anywhere.
Vec3 random_point(std::mt19937& rng, bool integer) {
  std::uniform_int_distribution<int> grid(-2, 2);
  std::uniform_real_distribution<double> real(-2.0, 2.0);
  return integer ? Vec3(grid(rng), grid(rng), grid(rng)) : Vec3(real(rng), real(rng), real(rng));
}

TEST(Predicates, SegmentTetAgreesWithEndpointsAndFacesExactly) {
  // A segment meets a closed tetrahedron exactly when an end lies in it or it meets one of its
  // faces (both exact predicates). Small integer coordinates make segments through vertices,
  // along edges and in face planes common: there the floating-point clip must defer to the
  // exact test.
  std::mt19937 rng(7);
  int hits = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const auto point = [&] { return random_point(rng, trial % 2 == 0); };
    std::array<Vec3, 4> t{point(), point(), point(), point()};
    if (orient3d(t[0], t[1], t[2], t[3]) == Sign::kZero) {
      continue;
    }
    if (orient3d(t[0], t[1], t[2], t[3]) == Sign::kNegative) {
      std::swap(t[2], t[3]);  // locate_in_tet takes positively oriented tetrahedra
    }
    const Vec3 p = point();
    const Vec3 q = point();
    bool expected = locate_in_tet(p, t[0], t[1], t[2], t[3]) != TetLocation::kOutside ||
                    locate_in_tet(q, t[0], t[1], t[2], t[3]) != TetLocation::kOutside;
    for (int f = 0; f < 4 && !expected; ++f) {
      const auto& face = tet_local::kFaces[f];
      expected = segment_intersects_triangle(p, q, t[face[0]], t[face[1]], t[face[2]]);
    }
    ASSERT_EQ(segment_intersects_tet(p, q, t[0], t[1], t[2], t[3]), expected) << "trial " << trial;
    hits += expected ? 1 : 0;
  }
  EXPECT_GT(hits, 1000);
}

TEST(Predicates, TriangleTetAgreesWithEdgesExactly) {
  // A triangle meets a tetrahedron exactly when one of its edges meets the tetrahedron or one
  // of the tetrahedron's edges meets the triangle: the filters before the exact test must not
  // change a single answer, on integer grids (touching cases) as on random points.
  // A third of the trials put the triangle in the plane x = 0 and the tetrahedron on one side
  // of it with corners in it (a blade along a plane of mesh faces): the exact 2-D test of
  // the part in the plane.
  std::mt19937 rng(11);
  int hits = 0;
  int touching = 0;
  for (int trial = 0; trial < 30000; ++trial) {
    const auto point = [&] { return random_point(rng, trial % 3 == 0); };
    std::array<Vec3, 4> t{point(), point(), point(), point()};
    std::array<Vec3, 3> tri{point(), point(), point()};
    if (trial % 3 == 2) {
      std::uniform_int_distribution<int> grid(-2, 2);
      for (Vec3& corner : tri) {
        corner = Vec3(0.0, grid(rng), grid(rng));
      }
      for (Vec3& corner : t) {
        corner = Vec3(grid(rng) < 0 ? 0.0 : std::abs(corner.x()), grid(rng), grid(rng));
      }
      touching += std::any_of(t.begin(), t.end(), [](const Vec3& x) { return x.x() == 0.0; });
    }
    if (orient3d(t[0], t[1], t[2], t[3]) == Sign::kZero ||
        (tri[1] - tri[0]).cross(tri[2] - tri[0]).squaredNorm() == 0.0) {
      continue;
    }
    bool expected = false;
    for (int k = 0; k < 3 && !expected; ++k) {
      expected = segment_intersects_tet(tri[k], tri[(k + 1) % 3], t[0], t[1], t[2], t[3]);
    }
    for (const auto& e : tet_local::kEdges) {
      expected = expected || segment_intersects_triangle(t[e[0]], t[e[1]], tri[0], tri[1], tri[2]);
    }
    ASSERT_EQ(triangle_intersects_tet(tri[0], tri[1], tri[2], t[0], t[1], t[2], t[3]), expected)
        << "trial " << trial;
    hits += expected ? 1 : 0;
  }
  EXPECT_GT(hits, 1000);
  EXPECT_GT(touching, 5000);
  // Apart only along the line of the tetrahedron's edge in the plane (no edge of the triangle
  // separates them), then touching at a corner; the triangle both ways round.
  for (bool flip : {false, true}) {
    const Vec3 low(0.0, 0.0, -1.0);
    Vec3 left(0.0, -1.0, 1.0);
    Vec3 right(0.0, 1.0, 1.0);
    if (flip) {
      std::swap(left, right);
    }
    for (double z : {-2.0, -1.0}) {
      const bool expected = z == -1.0;
      EXPECT_EQ(triangle_intersects_tet(low, left, right, Vec3(0.0, -2.0, z), Vec3(0.0, 2.0, z),
                                        Vec3(1.0, 0.0, z), Vec3(1.0, 0.0, z - 1.0)),
                expected)
          << "flip " << flip << " z " << z;
    }
  }
}

TEST(Predicates, LocateInTet) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), d(0, 0, 1);
  EXPECT_EQ(locate_in_tet(Vec3(0.1, 0.1, 0.1), a, b, c, d), TetLocation::kInside);
  EXPECT_EQ(locate_in_tet(Vec3(0.5, 0.5, 0.0), a, b, c, d), TetLocation::kBoundary);
  EXPECT_EQ(locate_in_tet(Vec3(0.5, 0.5, 0.5), a, b, c, d), TetLocation::kOutside);
  EXPECT_EQ(locate_in_tet(a, a, b, c, d), TetLocation::kBoundary);
}

TEST(Quality, RegularTetrahedron) {
  const Vec3 a(1, 1, 1), b(1, -1, -1), c(-1, 1, -1), d(-1, -1, 1);
  const double dihedral = std::acos(1.0 / 3.0);
  EXPECT_NEAR(min_dihedral_angle(a, b, c, d), dihedral, 1e-12);
  EXPECT_NEAR(aspect_ratio(a, b, c, d), 1.0, 1e-12);
}

TEST(Quality, CornerTetrahedron) {
  // The corner tet of the unit cube has three right dihedral angles and three of
  // acos(1/sqrt(3)) = 54.7356 deg: the minimum is the latter.
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), d(0, 0, 1);
  EXPECT_NEAR(min_dihedral_angle(a, b, c, d), std::acos(1.0 / std::sqrt(3.0)), 1e-12);
  EXPECT_GT(aspect_ratio(a, b, c, d), 1.0);
  EXPECT_TRUE(std::isinf(aspect_ratio(a, b, c, Vec3(1, 1, 0))));
}

TEST(Boundary, SingleTetFacesPointOutward) {
  const TetMesh mesh = test::unit_tet();
  const auto faces = boundary_faces(mesh);
  ASSERT_EQ(faces.size(), 4u);
  const Vec3 centroid(0.25, 0.25, 0.25);
  for (const BoundaryFace& face : faces) {
    const Vec3& p0 = mesh.rest_position(face.vertices[0]);
    const Vec3& p1 = mesh.rest_position(face.vertices[1]);
    const Vec3& p2 = mesh.rest_position(face.vertices[2]);
    const Vec3 normal = (p1 - p0).cross(p2 - p0);
    EXPECT_GT(normal.dot(p0 - centroid), 0.0) << "face " << face.local_face;
    EXPECT_EQ(face.tet, 0);
  }
  EXPECT_TRUE(check_boundary(mesh).watertight());
}

TEST(Boundary, OpenAndMisorientedSurfacesAreDetected) {
  std::vector<Triangle> closed{{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  EXPECT_TRUE(check_surface_edges(closed).watertight());
  std::vector<Triangle> open(closed.begin(), closed.end() - 1);
  EXPECT_EQ(check_surface_edges(open).open_edges, 3u);
  std::vector<Triangle> flipped = closed;
  std::swap(flipped[0][1], flipped[0][2]);
  EXPECT_EQ(check_surface_edges(flipped).misoriented_edges, 3u);
  // is_watertight says the same, as the faster check the renderer runs after every cut.
  EXPECT_TRUE(is_watertight(closed));
  EXPECT_FALSE(is_watertight(open));
  EXPECT_FALSE(is_watertight(flipped));
  // Every edge used twice each way (two copies) is closed; a third copy of one face is not,
  // though every edge is then used: the counts each way differ.
  std::vector<Triangle> doubled = closed;
  doubled.insert(doubled.end(), closed.begin(), closed.end());
  EXPECT_TRUE(is_watertight(doubled));
  doubled.push_back(closed[1]);
  EXPECT_FALSE(is_watertight(doubled));
  // A degenerate triangle's edge from a vertex to itself balances itself.
  std::vector<Triangle> with_degenerate = closed;
  with_degenerate.push_back({2, 2, 2});
  EXPECT_TRUE(is_watertight(with_degenerate));
  // Two closed surfaces, one with large vertex ids, and the whole body's boundary.
  std::vector<Triangle> two = closed;
  for (const Triangle& t : closed) {
    two.push_back({t[0] + 2000000000, t[1] + 2000000000, t[2] + 2000000000});
  }
  EXPECT_TRUE(is_watertight(two));
  two.pop_back();
  EXPECT_FALSE(is_watertight(two));
  EXPECT_FALSE(is_watertight(std::vector<Triangle>{{0, 1, 2}, {0, 1, 2}}));
  EXPECT_TRUE(is_watertight(std::vector<Triangle>{{0, 1, 2}, {0, 2, 1}}));
  // As many edges used upwards as downwards, but not the same ones.
  EXPECT_FALSE(is_watertight(std::vector<Triangle>{{0, 1, 2}, {3, 5, 4}}));
}

TEST(Components, SeparatedBoxes) {
  BoxGridOptions options;
  options.cells = {2, 2, 2};
  TetMesh first = make_box_grid(options);
  options.origin = Vec3(5, 0, 0);
  const TetMesh second = make_box_grid(options);
  std::vector<Vec3> positions(first.rest_positions().begin(), first.rest_positions().end());
  std::vector<Tet> tets(first.tets().begin(), first.tets().end());
  const auto offset = static_cast<VertexId>(positions.size());
  positions.insert(positions.end(), second.rest_positions().begin(), second.rest_positions().end());
  for (Tet tet : second.tets()) {
    for (VertexId& v : tet) {
      v += offset;
    }
    tets.push_back(tet);
  }
  const TetMesh both(positions, tets);
  int count = 0;
  const auto component = tet_components(both, &count);
  EXPECT_EQ(count, 2);
  EXPECT_EQ(component.front(), 0);
  EXPECT_EQ(component.back(), 1);
}

}  // namespace
}  // namespace incise
