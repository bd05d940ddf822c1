// XFEM element maths: a tetrahedron split by a cut has side volumes that are exact (against
// closed forms and an independent convex-hull computation), sum to the whole, and add up over
// a mesh to the exactly clipped volume of the body; virtual elements take real corners on
// their side and copies on the other.

#include "incise/xfem/element_cut.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>
#include <gtest/gtest.h>

#include <optional>
#include <random>

#include "incise/mesh/generators.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

double tet_volume(const std::array<Vec3, 4>& x) {
  return signed_volume(x[0], x[1], x[2], x[3]);
}

/// The volume of the convex hull of `points` (CGAL), independent of the code under test.
double hull_volume(const std::vector<Vec3>& points) {
  std::vector<Kernel::Point_3> cgal_points;
  for (const Vec3& p : points) {
    cgal_points.emplace_back(p.x(), p.y(), p.z());
  }
  CGAL::Surface_mesh<Kernel::Point_3> hull;
  CGAL::convex_hull_3(cgal_points.begin(), cgal_points.end(), hull);
  return CGAL::to_double(CGAL::Polygon_mesh_processing::volume(hull));
}

std::array<Vec3, 4> random_positive_tet(std::mt19937_64& random) {
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  while (true) {
    std::array<Vec3, 4> x;
    for (Vec3& p : x) {
      p = Vec3(coordinate(random), coordinate(random), coordinate(random));
    }
    if (tet_volume(x) < 0.0) {
      std::swap(x[2], x[3]);
    }
    if (tet_volume(x) > 0.02) {
      return x;
    }
  }
}

TEST(ElementCut, LoneCornerVolumeIsTheProductOfItsCrossings) {
  const std::array<Vec3, 4> x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  ElementCut cut;
  cut.on_b = {false, true, true, true};     // corner 0 alone on side a
  cut.crossing = {0.3, 0.5, 0.7, 0, 0, 0};  // edges 0-1, 0-2, 0-3
  const SideVolumes volumes = side_volumes(x, cut);
  EXPECT_NEAR(volumes.a, tet_volume(x) * 0.3 * 0.5 * 0.7, 1e-15);
  EXPECT_NEAR(volumes.a + volumes.b, tet_volume(x), 1e-15);
  // The same corner alone on side b: the sides swap.
  ElementCut swapped = cut;
  swapped.on_b = {true, false, false, false};
  EXPECT_NEAR(side_volumes(x, swapped).b, volumes.a, 1e-15);
}

TEST(ElementCut, PlanarCutsMatchTheClippedConvexHull) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int two_two = 0;
  int one_three = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const std::array<Vec3, 4> x = random_positive_tet(random);
    const Vec3 normal = Vec3(unit(random), unit(random), unit(random)).normalized();
    const Vec3 point =
        (x[0] + x[1] + x[2] + x[3]) / 4.0 + 0.3 * Vec3(unit(random), unit(random), unit(random));
    const auto cut = cut_by_plane(x, point, normal);
    if (!cut) {
      continue;
    }
    const auto on_b = std::count(cut->on_b.begin(), cut->on_b.end(), true);
    ++(on_b == 2 ? two_two : one_three);
    const SideVolumes volumes = side_volumes(x, *cut);
    std::vector<Vec3> side_a = cut_polygon(x, *cut);
    for (std::size_t k = 0; k < 4; ++k) {
      if (!cut->on_b[k]) {
        side_a.push_back(x[k]);
      }
    }
    EXPECT_NEAR(volumes.a, hull_volume(side_a), 1e-12) << trial;
    EXPECT_NEAR(volumes.fraction_a() + volumes.fraction_b(), 1.0, 1e-14);
    EXPECT_GE(volumes.a, 0.0);
    EXPECT_GE(volumes.b, 0.0);
  }
  EXPECT_GT(two_two, 100);
  EXPECT_GT(one_three, 100);
}

TEST(ElementCut, CurvedCutsStillSumToTheWholeAndMoveWithTheirCrossings) {
  // Crossings from a curved surface: four points that are not coplanar.
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> t(0.05, 0.95);
  for (int trial = 0; trial < 500; ++trial) {
    const std::array<Vec3, 4> x = random_positive_tet(random);
    ElementCut cut;
    cut.on_b = {false, true, false, true};
    for (double& crossing : cut.crossing) {
      crossing = t(random);
    }
    const SideVolumes volumes = side_volumes(x, cut);
    EXPECT_NEAR(volumes.a + volumes.b, tet_volume(x), 1e-14);
    EXPECT_GT(volumes.a, 0.0);
    EXPECT_GT(volumes.b, 0.0);
    // The complementary description (sides swapped) gives the same two volumes.
    ElementCut swapped = cut;
    for (bool& side : swapped.on_b) {
      side = !side;
    }
    EXPECT_NEAR(side_volumes(x, swapped).a, volumes.b, 1e-14);
    // Moving a crossing towards side b's corner grows side a (edge 0-1 runs from a to b).
    ElementCut further = cut;
    further.crossing[0] = std::min(0.99, cut.crossing[0] + 0.02);
    EXPECT_GT(side_volumes(x, further).a, volumes.a);
  }
}

TEST(ElementCut, FractionsOverAMeshAddUpToTheExactlyClippedBody) {
  // A unit cube of 6 x 5 x 4 cells cut by the oblique plane x + 0.5 y + 0.25 z = 0.9: the side
  // below it has a volume known in closed form.
  const TetMesh mesh = make_box_grid({{6, 5, 4}, Vec3(1, 1, 1), Vec3::Zero(), 6});
  const Vec3 normal = Vec3(1.0, 0.5, 0.25);
  const Vec3 point(0.9, 0.0, 0.0);
  double below = 0.0;
  int split = 0;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    std::array<Vec3, 4> x;
    for (std::size_t k = 0; k < 4; ++k) {
      x[k] = mesh.rest_position(tet[k]);
    }
    if (const auto cut = cut_by_plane(x, point, normal)) {
      below += side_volumes(x, *cut).a;
      ++split;
    } else if ((x[0] + x[1] + x[2] + x[3] - 4.0 * point).dot(normal) < 0.0) {
      below += tet_volume(x);
    }
  }
  // Volume of {x + y/2 + z/4 <= 0.9} in the unit cube: integrate over y, z the clamp of
  // 0.9 - y/2 - z/4 to [0, 1] (never above 1 or below 0.15 here, so simply its mean).
  const double exact = 0.9 - 0.25 - 0.125;
  EXPECT_GT(split, 50);
  EXPECT_NEAR(below, exact, 1e-12);
}

/// Two triangles spanning the square of half-size `half` around `centre` in the plane with
/// unit normal `normal` (their normal), limited to the side of `centre` along `keep` if given.
std::vector<std::array<Vec3, 3>> square(const Vec3& centre, const Vec3& normal, double half,
                                        const std::optional<Vec3>& keep = std::nullopt) {
  const Vec3 u = normal.unitOrthogonal();
  const Vec3 w = normal.cross(u);
  Vec3 low_u = centre - half * u;
  Vec3 high_u = centre + half * u;
  if (keep) {  // half of the square: only the part along `keep` (projected onto the plane)
    const Vec3 along = (*keep - keep->dot(normal) * normal).normalized();
    const Vec3 across = normal.cross(along);
    const Vec3 a = centre - half * across;
    const Vec3 b = centre + half * across;
    const Vec3 c = b + half * along;
    const Vec3 d = a + half * along;
    return {{a, b, c}, {a, c, d}};
  }
  const Vec3 a = low_u - half * w;
  const Vec3 b = high_u - half * w;
  const Vec3 c = high_u + half * w;
  const Vec3 d = low_u + half * w;
  return {{a, b, c}, {a, c, d}};
}

TEST(ElementCut, ASweptSurfaceThatCrossesCompletelyCutsAsItsPlane) {
  std::mt19937_64 random(13);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int compared = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    const std::array<Vec3, 4> x = random_positive_tet(random);
    const Vec3 normal = Vec3(unit(random), unit(random), unit(random)).normalized();
    const Vec3 centre =
        (x[0] + x[1] + x[2] + x[3]) / 4.0 + 0.2 * Vec3(unit(random), unit(random), unit(random));
    const auto by_plane = cut_by_plane(x, centre, normal);
    const auto triangles = square(centre, normal, 10.0);
    ASSERT_NEAR(((triangles[0][1] - triangles[0][0]).cross(triangles[0][2] - triangles[0][0]))
                    .normalized()
                    .dot(normal),
                1.0, 1e-12);
    std::uint8_t crossed = 0;
    const auto by_surface = cut_by_surface(x, triangles, &crossed);
    ASSERT_EQ(by_plane.has_value(), by_surface.has_value()) << trial;
    if (!by_plane) {
      EXPECT_EQ(crossed, 0);
      continue;
    }
    ++compared;
    EXPECT_EQ(by_plane->on_b, by_surface->on_b) << trial;
    for (std::size_t k = 0; k < 6; ++k) {
      if ((crossed >> k) & 1u) {
        EXPECT_NEAR(by_plane->crossing[k], by_surface->crossing[k], 1e-9) << trial;
      }
    }
  }
  EXPECT_GT(compared, 300);
}

TEST(ElementCut, APartlyCrossedTetrahedronWaitsForTheBlade) {
  // A surface that ends at the tetrahedron's centroid reaches it without crossing it.
  std::mt19937_64 random(17);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int reached = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const std::array<Vec3, 4> x = random_positive_tet(random);
    const Vec3 normal = Vec3(unit(random), unit(random), unit(random)).normalized();
    const Vec3 centre = (x[0] + x[1] + x[2] + x[3]) / 4.0;
    const Vec3 keep(unit(random), unit(random), unit(random));
    std::uint8_t crossed = 0;
    const auto cut = cut_by_surface(x, square(centre, normal, 10.0, keep), &crossed);
    if (cut) {
      // Possible only if every edge the whole plane crosses lies on the kept side.
      const auto by_plane = cut_by_plane(x, centre, normal);
      ASSERT_TRUE(by_plane.has_value());
      EXPECT_EQ(cut->on_b, by_plane->on_b);
    } else if (crossed != 0) {
      ++reached;
    }
  }
  EXPECT_GT(reached, 100);
}

TEST(ElementCut, VirtualElementsTakeRealCornersOnTheirSide) {
  const Tet real = {10, 11, 12, 13};
  const Tet copies = {20, 21, 22, 23};
  ElementCut cut;
  cut.on_b = {false, true, true, false};
  const VirtualElements elements = virtual_elements(real, cut, copies);
  EXPECT_EQ(elements.a, (Tet{10, 21, 22, 13}));
  EXPECT_EQ(elements.b, (Tet{20, 11, 12, 23}));
  ElementCut whole;
  EXPECT_FALSE(whole.splits());
  EXPECT_TRUE(cut.splits());
}

}  // namespace
}  // namespace incise
