// Every reader on every file in ../shared/data it applies to. Expected counts come from
// ../shared/data/MANIFEST.md; expected volumes from an independent Python parser
// (tests/tools/reference_values.py).

#include <gtest/gtest.h>

#include <filesystem>

#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

struct VolumeCase {
  const char* file;
  MeshFormat format;
  std::size_t vertices;
  std::size_t tets;
  double volume;
  std::size_t inverted;
};

void PrintTo(const VolumeCase& c, std::ostream* out) {
  *out << c.file;
}

class RealVolumeMeshes : public ::testing::TestWithParam<VolumeCase> {};

TEST_P(RealVolumeMeshes, CountsVolumeAndValidity) {
  const VolumeCase& expected = GetParam();
  const auto path = test::data_file(expected.file);
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP() << "test data not found: " << path;
  }
  EXPECT_EQ(detect_format(path), expected.format);
  const TetMeshReadResult read = read_tet_mesh(path);
  EXPECT_EQ(read.format, expected.format);
  EXPECT_EQ(read.mesh.vertex_count(), expected.vertices);
  EXPECT_EQ(read.mesh.tet_count(), expected.tets);
  EXPECT_EQ(read.dropped_vertices, 0u);
  EXPECT_NEAR(total_volume(read.mesh), expected.volume, 1e-12 * std::abs(expected.volume));
  const ValidationReport report = validate(read.mesh);
  EXPECT_EQ(report.inverted_tets.size(), expected.inverted) << report.describe();
  EXPECT_EQ(report.ok(), expected.inverted == 0) << report.describe();
  EXPECT_EQ(read.mesh.compare_with_rebuilt_adjacency(), "");
  // The boundary of every valid mesh here is closed and outward: its enclosed volume
  // (divergence theorem) equals the sum of tetrahedron volumes.
  if (expected.inverted == 0) {
    const auto faces = boundary_faces(read.mesh);
    double enclosed = 0.0;
    for (const BoundaryFace& face : faces) {
      const Vec3& a = read.mesh.rest_position(face.vertices[0]);
      const Vec3& b = read.mesh.rest_position(face.vertices[1]);
      const Vec3& c = read.mesh.rest_position(face.vertices[2]);
      enclosed += a.dot(b.cross(c)) / 6.0;
    }
    EXPECT_NEAR(enclosed, expected.volume, 1e-9 * std::abs(expected.volume));
    EXPECT_TRUE(check_boundary(read.mesh).watertight());
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealVolumeMeshes,
    ::testing::Values(
        VolumeCase{"sofa/liver.msh", MeshFormat::kGmsh, 181, 596, 36.56085106149485, 0},
        VolumeCase{"sofa/cylinder.msh", MeshFormat::kGmsh, 510, 2430, 0.1836825839831991, 0},
        VolumeCase{"sofa/cube_low_res.msh", MeshFormat::kGmsh, 26, 44, 343.0000000000077, 0},
        VolumeCase{"sofa/single_tetra.msh", MeshFormat::kGmsh, 4, 1, -12.5, 1},
        VolumeCase{"sofa/6_tetra_bad.msh", MeshFormat::kGmsh, 17, 6, 31.65, 1},
        VolumeCase{"sofa-mor/liverTinyMesh.vtu", MeshFormat::kVtkXml, 42, 86, 29.182267781039826,
                   0},
        VolumeCase{"sofa-mor/liverVeryCOARSE.vtu", MeshFormat::kVtkXml, 80, 225, 32.80848360456603,
                   0},
        VolumeCase{"sofa-mor/liverCoarse.vtu", MeshFormat::kVtkXml, 357, 1369, 37.298290032167756,
                   0},
        VolumeCase{"sofa-mor/liverSemiFine.vtu", MeshFormat::kVtkXml, 1375, 6444, 38.57136495801428,
                   0},
        VolumeCase{"pbd/armadillo_4k.ele", MeshFormat::kTetGen, 1180, 3717, 1.8596000544456597, 0},
        VolumeCase{"pbd/armadillo_4k.node", MeshFormat::kTetGen, 1180, 3717, 1.8596000544456597, 0},
        VolumeCase{"libigl/octopus-low.mesh", MeshFormat::kMedit, 452, 1140, 0.009135547847518207,
                   0}),
    [](const ::testing::TestParamInfo<VolumeCase>& param_info) {
      return test::test_name_from(param_info.param.file);
    });

TEST(RealVolumeMeshes, InvertedTetsAreTheOnesSofaMarked) {
  const auto path = test::data_file("sofa/6_tetra_bad.msh");
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP();
  }
  const TetMesh mesh = read_tet_mesh(path).mesh;
  const auto report = validate(mesh);
  ASSERT_EQ(report.inverted_tets.size(), 1u);
  EXPECT_LT(signed_volume(mesh, report.inverted_tets[0]), 0.0);
}

struct SurfaceCase {
  const char* file;
  MeshFormat format;
  std::size_t points;
  std::size_t triangles;
};

void PrintTo(const SurfaceCase& c, std::ostream* out) {
  *out << c.file;
}

class RealSurfaces : public ::testing::TestWithParam<SurfaceCase> {};

TEST_P(RealSurfaces, CountsAndClosedness) {
  const SurfaceCase& expected = GetParam();
  const auto path = test::data_file(expected.file);
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP() << "test data not found: " << path;
  }
  EXPECT_EQ(detect_format(path), expected.format);
  const SurfaceMesh surface = read_surface(path);
  EXPECT_EQ(surface.points.size(), expected.points);
  EXPECT_EQ(surface.triangles.size(), expected.triangles);
  for (const Triangle& t : surface.triangles) {
    for (VertexId v : t) {
      ASSERT_GE(v, 0);
      ASSERT_LT(static_cast<std::size_t>(v), surface.points.size());
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealSurfaces,
    ::testing::Values(SurfaceCase{"sofa/liver-smooth.obj", MeshFormat::kObj, 2194, 4384},
                      SurfaceCase{"sofa/liver.vtk", MeshFormat::kVtkLegacy, 5008, 10000},
                      SurfaceCase{"eit-mesher/NNscalp.stl", MeshFormat::kStl, 12704, 25404},
                      SurfaceCase{"eit-mesher/NNskull_lowpoly.STL", MeshFormat::kStl, 10000,
                                  20000}),
    [](const ::testing::TestParamInfo<SurfaceCase>& param_info) {
      return test::test_name_from(param_info.param.file);
    });

TEST(RealSurfaces, LiverObjIsTheBoundaryOfLiverMsh) {
  // liver.obj is SOFA's surface of liver.msh: same frame, enclosed volume close to the mesh's.
  const auto obj = test::data_file("sofa/liver.obj");
  const auto msh = test::data_file("sofa/liver.msh");
  if (!std::filesystem::exists(obj) || !std::filesystem::exists(msh)) {
    GTEST_SKIP();
  }
  const SurfaceMesh surface = read_surface(obj);
  EXPECT_EQ(surface.triangles.size(), 274u);
  double enclosed = 0.0;
  for (const Triangle& t : surface.triangles) {
    enclosed += surface.points[t[0]].dot(surface.points[t[1]].cross(surface.points[t[2]])) / 6.0;
  }
  EXPECT_NEAR(std::abs(enclosed), total_volume(read_tet_mesh(msh).mesh), 0.01 * 36.56);
}

TEST(FormatDetection, ContentWinsOverALyingExtension) {
  const auto source = test::data_file("sofa/liver.msh");
  if (!std::filesystem::exists(source)) {
    GTEST_SKIP();
  }
  const auto dir = test::scratch_dir("lying-extension");
  const auto liar = dir / "liver.vtk";
  std::filesystem::copy_file(source, liar);
  EXPECT_EQ(detect_format(liar), MeshFormat::kGmsh);
  EXPECT_EQ(read_tet_mesh(liar).mesh.tet_count(), 596u);
  const auto stl_source = test::data_file("eit-mesher/NNskull_lowpoly.STL");
  const auto stl_liar = dir / "skull.obj";
  std::filesystem::copy_file(stl_source, stl_liar);
  EXPECT_EQ(read_surface(stl_liar).triangles.size(), 20000u);
  const auto vtu_liar = dir / "tiny.mesh";
  std::filesystem::copy_file(test::data_file("sofa-mor/liverTinyMesh.vtu"), vtu_liar);
  EXPECT_EQ(read_tet_mesh(vtu_liar).mesh.tet_count(), 86u);
}

}  // namespace
}  // namespace incise
