// Tetrahedralisation with TetGen: valid output that fills the surface, clear errors (never a
// hang or a crash) for surfaces that bound no volume.

#include "incise/meshing/tetrahedralize.hpp"

#include <gtest/gtest.h>

#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/quality.hpp"
#include "incise/mesh/validate.hpp"
#include "test_support.hpp"
#include "test_surfaces.hpp"

namespace incise {
namespace {

using test::append_surface;
using test::box_surface;
using test::enclosed_volume;

TEST(Tetrahedralize, BoxFillsItsSurface) {
  const SurfaceMesh surface = box_surface();
  TetrahedralizeOptions options;
  options.max_volume = 0.001;
  const TetrahedralizeResult result = tetrahedralize(surface, options);
  const ValidationReport report = validate(result.mesh);
  EXPECT_TRUE(report.ok()) << report.describe();
  EXPECT_NEAR(total_volume(result.mesh), 1.0, 1e-12);
  EXPECT_TRUE(check_boundary(result.mesh).watertight());
  for (std::size_t t = 0; t < result.mesh.tet_count(); ++t) {
    EXPECT_LE(signed_volume(result.mesh, static_cast<TetId>(t)), 0.001 * (1 + 1e-9));
  }
  EXPECT_GT(result.mesh.tet_count(), 1000u);
  // The quality bound holds: TetGen's radius-edge bound 1.5 keeps tets from flattening.
  EXPECT_GT(summarize_quality(result.mesh).min_dihedral_deg, 5.0);
}

TEST(Tetrahedralize, SofaLiverSurface) {
  const auto path = test::data_file("sofa/liver.obj");
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP();
  }
  const SurfaceMesh surface = read_surface(path);
  const TetrahedralizeResult result = tetrahedralize(surface);
  EXPECT_TRUE(validate(result.mesh).ok()) << validate(result.mesh).describe();
  // TetGen rounds the Steiner points it puts on boundary facets: 1e-7 relative, not 1e-15.
  EXPECT_NEAR(total_volume(result.mesh), std::abs(enclosed_volume(surface)),
              1e-7 * std::abs(enclosed_volume(surface)));
  int components = 0;
  (void)tet_components(result.mesh, &components);
  EXPECT_EQ(components, 1);
}

TEST(Tetrahedralize, SofaLiverVtkKeepsEveryShellOrTheLargest) {
  const auto path = test::data_file("sofa/liver.vtk");
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP();
  }
  const SurfaceMesh surface = read_surface(path);
  const auto shells = surface_shells(surface);
  ASSERT_EQ(shells.size(), 4u);  // the organ and three stray closed bits in the file
  EXPECT_EQ(shells.front().triangles.size(), 9988u);
  TetrahedralizeOptions options;
  options.max_volume = 100.0;  // mm^3
  const TetrahedralizeResult whole = tetrahedralize(surface, options);
  int components = 0;
  (void)tet_components(whole.mesh, &components);
  EXPECT_EQ(components, 4);
  const TetrahedralizeResult organ = tetrahedralize(shells.front(), options);
  EXPECT_TRUE(validate(organ.mesh).ok()) << validate(organ.mesh).describe();
  EXPECT_NEAR(total_volume(organ.mesh), std::abs(enclosed_volume(shells.front())),
              1e-7 * std::abs(enclosed_volume(shells.front())));
}

TEST(Tetrahedralize, NeonatalScalpNeedsRemeshing) {
  const auto path = test::data_file("eit-mesher/NNscalp.stl");
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP();
  }
  const SurfaceMesh surface = read_surface(path);
  EXPECT_LT(min_triangle_angle_deg(surface), 0.01);  // needle triangles from the scan
  const TetrahedralizeResult result = tetrahedralize(surface);
  ASSERT_FALSE(result.notes.empty());
  EXPECT_NE(result.notes.front().find("remeshed"), std::string::npos);
  const ValidationReport report = validate(result.mesh);
  EXPECT_TRUE(report.ok()) << report.describe();
  EXPECT_TRUE(check_boundary(result.mesh).watertight());
  // Remeshing moves the boundary by a fraction of an edge: the volume stays within 0.5 %.
  EXPECT_NEAR(total_volume(result.mesh), std::abs(enclosed_volume(surface)),
              0.005 * std::abs(enclosed_volume(surface)));
}

TEST(Tetrahedralize, OpenSurfaceIsRejected) {
  SurfaceMesh surface = box_surface();
  surface.triangles.pop_back();
  try {
    (void)tetrahedralize(surface);
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("open edges"), std::string::npos) << error.what();
  }
}

TEST(Tetrahedralize, SelfIntersectingSurfaceIsRejected) {
  // Two overlapping closed boxes in one surface.
  SurfaceMesh surface = box_surface();
  append_surface(surface, box_surface(Vec3(0.5, 0.5, 0.5)));
  const SurfaceCheckReport check = check_closed_surface(surface);
  EXPECT_FALSE(check.self_intersections.empty());
  try {
    (void)tetrahedralize(surface);
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("self-intersection"), std::string::npos)
        << error.what();
  }
}

TEST(Tetrahedralize, InvertedOrientationIsRejected) {
  SurfaceMesh surface = box_surface();
  std::swap(surface.triangles[3][0], surface.triangles[3][1]);
  EXPECT_THROW((void)tetrahedralize(surface), InputError);
}

TEST(Tetrahedralize, TimeLimitStopsTetGen) {
  TetrahedralizeOptions options;
  options.max_volume = 1e-7;  // millions of tetrahedra: far beyond the limit below
  options.timeout_seconds = 0.2;
  try {
    (void)tetrahedralize(box_surface(), options);
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("did not finish within"), std::string::npos)
        << error.what();
  }
}

TEST(Tetrahedralize, BadOptions) {
  TetrahedralizeOptions options;
  options.max_radius_edge_ratio = 1.0;
  EXPECT_THROW((void)tetrahedralize(box_surface(), options), InputError);
  options = {};
  options.max_volume = -1.0;
  EXPECT_THROW((void)tetrahedralize(box_surface(), options), InputError);
}

TEST(SurfaceShells, SplitsDisjointPieces) {
  SurfaceMesh surface = box_surface();
  append_surface(surface, box_surface(Vec3(5, 5, 5), 0.1));
  const auto shells = surface_shells(surface);
  ASSERT_EQ(shells.size(), 2u);
  EXPECT_NEAR(enclosed_volume(shells[0]), 1.0, 1e-12);
  EXPECT_NEAR(enclosed_volume(shells[1]), 1e-3, 1e-12);
}

}  // namespace
}  // namespace incise
