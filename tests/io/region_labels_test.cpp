// Region labels: each reader keeps a file's per-tetrahedron regions (Gmsh physical, else
// elementary tags; MEDIT references; TetGen region attributes; the first integer VTU cell
// array), and each writer that can hold them writes them back.

#include <gtest/gtest.h>

#include <fstream>
#include <map>

#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/generators.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

std::filesystem::path write_text(const std::string& name, const std::string& text) {
  const auto path = test::scratch_dir("labels") / name;
  std::ofstream(path) << text;
  return path;
}

std::vector<int> labels_of(const std::filesystem::path& path) {
  const TetMesh mesh = read_tet_mesh(path).mesh;
  return {mesh.tet_labels().begin(), mesh.tet_labels().end()};
}

// Each file: two tetrahedra sharing a face, in two regions.

TEST(RegionLabels, GmshVersion2PhysicalElseElementary) {
  // Tag lists: (physical 5, elementary 9) and (physical 0, elementary 9): the second falls back.
  const auto path = write_text("v2.msh",
                               "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0 "
                               "0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n$EndNodes\n$Elements\n2\n"
                               "1 4 2 5 9 1 2 3 4\n2 4 2 0 9 2 3 4 5\n$EndElements\n");
  EXPECT_EQ(labels_of(path), (std::vector<int>{5, 9}));
}

TEST(RegionLabels, GmshVersion4PhysicalGroupsFromEntities) {
  // Volume entity 1 is in physical group 7; volume entity 2 is in none: region 0, as incise
  // writes label 0 (Gmsh has no physical group 0), so a written mesh reads back as it was.
  const auto path = write_text(
      "v4.msh",
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 2\n"
      "1 0 0 0 1 1 1 1 7 0\n2 0 0 0 1 1 1 0 0\n$EndEntities\n"
      "$Nodes\n1 5 1 5\n3 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n$EndNodes\n"
      "$Elements\n2 2 1 2\n3 1 4 1\n1 1 2 3 4\n3 2 4 1\n2 2 3 4 5\n$EndElements\n");
  EXPECT_EQ(labels_of(path), (std::vector<int>{7, 0}));
}

TEST(RegionLabels, MeditReferencesAndTetgenAttributes) {
  const auto medit = write_text("two.mesh", std::string("MeshVersionFormatted 2\nDimension 3\n"
                                                        "Vertices\n5\n") +
                                                "0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n1 1 1 0\n"
                                                "Tetrahedra\n2\n1 2 3 4 3\n2 3 4 5 11\nEnd\n");
  EXPECT_EQ(labels_of(medit), (std::vector<int>{3, 11}));
  (void)write_text("two.node", std::string("5 3 0 0\n0 ") +
                                   "0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n"
                                   "4 1 1 1\n");
  const auto ele = write_text("two.ele", "2 4 1\n0 0 1 2 3 -4\n1 1 2 3 4 6\n");
  EXPECT_EQ(labels_of(ele), (std::vector<int>{-4, 6}));
  const auto fractional = write_text("bad.ele", "2 4 1\n0 0 1 2 3 1.5\n1 1 2 3 4 6\n");
  (void)write_text("bad.node", "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 1\n");
  try {
    (void)read_tet_mesh(fractional);
    FAIL() << "a fractional region attribute was taken as a label";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("not an integer label"), std::string::npos)
        << error.what();
  }
}

TEST(RegionLabels, LegacyVtkCellDataScalarsOrFieldArrays) {
  const std::string geometry =
      "# vtk DataFile Version 3.0\ntwo\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n"
      "0 0 0 1 0 0 0 1 0 0 0 1 1 1 1\nCELLS 2 10\n4 0 1 2 3\n4 1 2 3 4\nCELL_TYPES 2\n10 10\n";
  // Point data first, a float cell array, then the integer one: it is the labels.
  const auto scalars = write_text(
      "scalars.vtk", geometry +
                         "POINT_DATA 5\nSCALARS t float\nLOOKUP_TABLE default\n"
                         "0 1 2 3 4\nCELL_DATA 2\nSCALARS q double 1\nLOOKUP_TABLE "
                         "default\n0.5 0.7\nSCALARS region int 1\nLOOKUP_TABLE default\n8 3\n");
  EXPECT_EQ(labels_of(scalars), (std::vector<int>{8, 3}));
  const auto field = write_text("field.vtk", geometry +
                                                 "CELL_DATA 2\nFIELD FieldData 2\n"
                                                 "quality 1 2 double\n0.1 0.2\n"
                                                 "subdomain 1 2 int\n4 9\n");
  EXPECT_EQ(labels_of(field), (std::vector<int>{4, 9}));
  // No attribute data: label 0; unreadable attribute data: the mesh is still read.
  EXPECT_EQ(labels_of(write_text("plain.vtk", geometry)), (std::vector<int>{0, 0}));
  EXPECT_EQ(labels_of(write_text("broken.vtk", geometry + "CELL_DATA 2\nSCALARS r int\n"
                                                          "LOOKUP_TABLE default\n1\n")),
            (std::vector<int>{0, 0}));
}

TEST(RegionLabels, AVtkLabelArrayChosenByName) {
  BoxGridOptions options;
  options.cells = {1, 1, 1};
  const TetMesh grid = make_box_grid(options);
  VtuFields fields;
  fields.cell_data.push_back({"material", 1, std::vector<std::int32_t>{1, 1, 1, 2, 2, 2}});
  fields.cell_data.push_back({"subdomain", 1, std::vector<std::int32_t>{7, 7, 8, 8, 9, 9}});
  fields.cell_data.push_back({"quality", 1, std::vector<double>{0.5, 0.5, 0.5, 0.5, 0.5, 0.5}});
  const auto path = test::scratch_dir("labels-named") / "named.vtu";
  write_vtu(path, grid, {}, fields);
  const auto labels = [&](const std::string& name) {
    const TetMesh mesh = read_tet_mesh(path, ReadOptions{name}).mesh;
    return std::vector<int>(mesh.tet_labels().begin(), mesh.tet_labels().end());
  };
  EXPECT_EQ(labels(""), (std::vector<int>{1, 1, 1, 2, 2, 2}));  // the first integer array
  EXPECT_EQ(labels("subdomain"), (std::vector<int>{7, 7, 8, 8, 9, 9}));
  try {
    (void)labels("regions");
    FAIL();
  } catch (const InputError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find("no cell array named 'regions'"), std::string::npos) << what;
    EXPECT_NE(what.find("material, subdomain, quality"), std::string::npos) << what;
  }
  // A named array of fractions is not labels.
  fields.cell_data.back() = {"quality", 1, std::vector<double>{0.5, 1, 1, 1, 1, 1}};
  write_vtu(path, grid, {}, fields);
  EXPECT_THROW((void)labels("quality"), InputError);
  // The same in a legacy file.
  const std::string legacy =
      "# vtk DataFile Version 3.0\ntwo\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n"
      "0 0 0 1 0 0 0 1 0 0 0 1 1 1 1\nCELLS 2 10\n4 0 1 2 3\n4 1 2 3 4\nCELL_TYPES 2\n10 10\n"
      "CELL_DATA 2\nSCALARS a int 1\nLOOKUP_TABLE default\n1 2\nSCALARS b int 1\n"
      "LOOKUP_TABLE default\n5 6\n";
  const auto vtk = write_text("named.vtk", legacy);
  EXPECT_EQ(read_tet_mesh(vtk, ReadOptions{"b"}).mesh.tet_label(1), 6);
  EXPECT_THROW((void)read_tet_mesh(vtk, ReadOptions{"c"}), InputError);
}

TEST(RegionLabels, EveryWriterWritesThemBack) {
  BoxGridOptions options;
  options.cells = {4, 2, 2};
  const TetMesh grid = make_box_grid(options);
  std::vector<int> labels(grid.tet_count());
  for (std::size_t t = 0; t < labels.size(); ++t) {
    labels[t] = t % 3 == 0 ? 4 : (t % 3 == 1 ? 0 : 12);
  }
  const TetMesh mesh(std::vector<Vec3>(grid.rest_positions().begin(), grid.rest_positions().end()),
                     std::vector<Tet>(grid.tets().begin(), grid.tets().end()), labels);
  for (const char* extension : {".vtu", ".mesh", ".node", ".msh"}) {
    const auto path = test::scratch_dir("labels-out") / (std::string("grid") + extension);
    write_tet_mesh(path, mesh);
    const TetMesh read = read_tet_mesh(path).mesh;
    ASSERT_EQ(read.tet_count(), mesh.tet_count()) << extension;
    // Gmsh groups tetrahedra by region (label 0 in an entity without a physical group, which
    // reads back as 0): compare tets per label there, the exact order elsewhere.
    if (std::string(extension) == ".msh") {
      std::map<int, int> counts;
      for (int label : read.tet_labels()) {
        ++counts[label];
      }
      EXPECT_EQ(counts[4], static_cast<int>(std::count(labels.begin(), labels.end(), 4)));
      EXPECT_EQ(counts[12], static_cast<int>(std::count(labels.begin(), labels.end(), 12)));
      EXPECT_EQ(counts[0], static_cast<int>(std::count(labels.begin(), labels.end(), 0)));
      EXPECT_EQ(counts.size(), 3U);
    } else {
      EXPECT_EQ(std::vector<int>(read.tet_labels().begin(), read.tet_labels().end()), labels)
          << extension;
    }
  }
}

}  // namespace
}  // namespace incise
