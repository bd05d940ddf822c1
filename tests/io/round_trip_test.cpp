// Every writer, read back: positions bit-exact, tetrahedra identical, fields intact.

#include <gtest/gtest.h>

#include <fstream>
#include <pugixml.hpp>

#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

/// A mesh whose coordinates need all 17 significant digits.
TetMesh awkward_mesh() {
  BoxGridOptions options;
  options.cells = {3, 2, 2};
  options.size = Vec3(0.1 / 3.0, std::sqrt(2.0) / 100.0, 1e-3 * std::numbers::pi);
  options.origin = Vec3(-1.0 / 7.0, 1e-9, 12345.678901234567);
  options.tets_per_cell = 5;
  return make_box_grid(options);
}

void expect_identical(const TetMesh& a, const TetMesh& b) {
  ASSERT_EQ(a.vertex_count(), b.vertex_count());
  ASSERT_EQ(a.tet_count(), b.tet_count());
  for (std::size_t v = 0; v < a.vertex_count(); ++v) {
    ASSERT_EQ(a.rest_position(static_cast<VertexId>(v)), b.rest_position(static_cast<VertexId>(v)))
        << "vertex " << v;
  }
  for (std::size_t t = 0; t < a.tet_count(); ++t) {
    ASSERT_EQ(a.tet(static_cast<TetId>(t)), b.tet(static_cast<TetId>(t))) << "tet " << t;
  }
}

class WriterRoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(WriterRoundTrip, ReadsBackExactly) {
  const TetMesh mesh = awkward_mesh();
  const auto path = test::scratch_dir("round-trip") / ("mesh" + GetParam());
  write_tet_mesh(path, mesh);
  const TetMeshReadResult read = read_tet_mesh(path);
  expect_identical(mesh, read.mesh);
  EXPECT_TRUE(read.notes.empty() || GetParam() == ".mesh");  // MEDIT carries its boundary
}

INSTANTIATE_TEST_SUITE_P(Formats, WriterRoundTrip,
                         ::testing::Values(".msh", ".vtu", ".mesh", ".node", ".ele"),
                         [](const ::testing::TestParamInfo<std::string>& param_info) {
                           return param_info.param.substr(1);
                         });

TEST(WriterRoundTrip, RealMeshThroughEveryFormat) {
  const auto source = test::data_file("pbd/armadillo_4k.ele");
  if (!std::filesystem::exists(source)) {
    GTEST_SKIP();
  }
  const TetMesh original = read_tet_mesh(source).mesh;
  const auto dir = test::scratch_dir("round-trip-real");
  TetMesh current = original;
  for (const char* extension : {".msh", ".vtu", ".mesh", ".node"}) {
    const auto path = dir / (std::string("armadillo") + extension);
    write_tet_mesh(path, current);
    current = read_tet_mesh(path).mesh;
  }
  expect_identical(original, current);
}

TEST(WriterRoundTrip, ObjBoundarySurface) {
  const TetMesh mesh = awkward_mesh();
  const auto path = test::scratch_dir("obj") / "surface.obj";
  write_obj(path, mesh);
  const SurfaceMesh surface = read_surface(path);
  EXPECT_EQ(surface.triangles.size(), boundary_faces(mesh).size());
  EXPECT_TRUE(check_surface_edges(surface.triangles).watertight());
  const auto vtp = path.parent_path() / "surface.vtp";
  write_vtp(vtp, surface.points, surface.triangles);
  const SurfaceMesh again = read_surface(vtp);
  EXPECT_EQ(again.triangles, surface.triangles);
  EXPECT_EQ(again.points, surface.points);
}

TEST(VtuWriter, PointAndCellDataAreReadable) {
  const TetMesh mesh = awkward_mesh();
  VtuFields fields;
  std::vector<double> displacement(3 * mesh.vertex_count());
  for (std::size_t i = 0; i < displacement.size(); ++i) {
    displacement[i] = 0.001 * static_cast<double>(i);
  }
  std::vector<std::int32_t> ids(mesh.tet_count());
  for (std::size_t t = 0; t < ids.size(); ++t) {
    ids[t] = static_cast<std::int32_t>(t);
  }
  fields.point_data.push_back({"displacement", 3, displacement});
  fields.cell_data.push_back({"tet_id", 1, ids});
  const auto path = test::scratch_dir("vtu-fields") / "fields.vtu";
  std::vector<Vec3> moved(mesh.rest_positions().begin(), mesh.rest_positions().end());
  for (Vec3& p : moved) {
    p.z() += 1.0;
  }
  write_vtu(path, mesh, moved, fields);
  const TetMesh read = read_tet_mesh(path).mesh;
  EXPECT_EQ(read.rest_position(3), moved[3]);
  // The XML names the arrays where ParaView looks for them.
  pugi::xml_document document;
  std::ifstream stream(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  ASSERT_TRUE(document.load_string(text.c_str()));
  const auto piece = document.child("VTKFile").child("UnstructuredGrid").child("Piece");
  EXPECT_STREQ(piece.child("PointData").child("DataArray").attribute("Name").value(),
               "displacement");
  EXPECT_STREQ(piece.child("CellData").child("DataArray").attribute("Name").value(), "tet_id");
}

TEST(VtuWriter, RefusesNaN) {
  const TetMesh mesh = awkward_mesh();
  std::vector<Vec3> positions(mesh.rest_positions().begin(), mesh.rest_positions().end());
  positions[5].x() = std::numeric_limits<double>::quiet_NaN();
  const auto path = test::scratch_dir("vtu-nan") / "nan.vtu";
  EXPECT_THROW(write_vtu(path, mesh, positions), InputError);
  EXPECT_FALSE(std::filesystem::exists(path));  // nothing half-written left behind
  VtuFields fields;
  fields.point_data.push_back(
      {"bad", 1,
       std::vector<double>(mesh.vertex_count(), std::numeric_limits<double>::infinity())});
  EXPECT_THROW(write_vtu(path, mesh, {}, fields), InputError);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(PvdSeries, ListsEveryFrameAfterEachAdd) {
  const auto dir = test::scratch_dir("pvd");
  PvdSeries series(dir / "run.pvd");
  const TetMesh mesh = awkward_mesh();
  for (int frame = 0; frame < 3; ++frame) {
    const std::string file = "frame_" + std::to_string(frame) + ".vtu";
    write_vtu(dir / file, mesh);
    series.add(0.1 * frame, file);
    pugi::xml_document document;
    ASSERT_TRUE(document.load_file((dir / "run.pvd").c_str()));
    int entries = 0;
    for (const auto dataset : document.child("VTKFile").child("Collection").children("DataSet")) {
      EXPECT_TRUE(std::filesystem::exists(dir / dataset.attribute("file").value()));
      ++entries;
    }
    EXPECT_EQ(entries, frame + 1);
  }
}

TEST(Writers, OverwritingTheInputIsSafe) {
  // Converting a file onto itself must not destroy it mid-way.
  const TetMesh mesh = awkward_mesh();
  const auto path = test::scratch_dir("self-overwrite") / "mesh.msh";
  write_msh(path, mesh);
  write_msh(path, read_tet_mesh(path).mesh);
  expect_identical(mesh, read_tet_mesh(path).mesh);
  std::size_t leftovers = 0;
  for (const auto& entry : std::filesystem::directory_iterator(path.parent_path())) {
    leftovers += entry.path() != path ? 1 : 0;
  }
  EXPECT_EQ(leftovers, 0u);
}

TEST(Writers, UnknownExtension) {
  EXPECT_THROW(write_tet_mesh(test::scratch_dir("bad-ext") / "mesh.xyz", awkward_mesh()),
               InputError);
}

}  // namespace
}  // namespace incise
