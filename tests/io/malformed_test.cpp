// Malformed input in every format: an InputError that names the file, the line where one
// exists, and what is wrong. Never a crash, never a silently wrong mesh.

#include <gtest/gtest.h>

#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "io_test_support.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

struct Malformed {
  const char* name;     ///< file name (the extension matters for ambiguous content)
  std::string content;  ///< file bytes
  const char* message;  ///< expected part of the error
  std::size_t line;     ///< expected line (0: none)
};

void PrintTo(const Malformed& c, std::ostream* out) {
  *out << c.name;
}

const std::string kMshHeader = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";  // lines 1-3
const std::string kMshNodes = "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";  // 4-10

std::string vtu_with(const std::string& cells) {
  return "<VTKFile type=\"UnstructuredGrid\">\n<UnstructuredGrid>\n"
         "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n<Points>\n"
         "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 "
         "0 0 "
         "1</DataArray>\n</Points>\n<Cells>\n" +
         cells + "\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
}

const std::string kVtuTypes =
    "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>";
const std::string kVtkHead = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n";

std::string truncated_binary_msh() {
  std::string bytes = "$MeshFormat\n2.2 1 8\n";
  test::put<std::int32_t>(bytes, 1);
  bytes += "\n$EndMeshFormat\n$Nodes\n4\n";
  test::put<std::int32_t>(bytes, 1);
  test::put<double>(bytes, 0.0);  // the file stops inside the first node
  return bytes;
}

/// A zlib-compressed .vtu whose connectivity header claims a 2 GB block from 10 bytes.
std::string zlib_bomb_vtu() {
  std::string header;
  for (std::uint32_t value : {1U, 1U << 31U, 1U << 31U, 10U}) {
    test::put<std::uint32_t>(header, value);
  }
  std::string text = vtu_with("<DataArray type=\"Int32\" Name=\"connectivity\" format=\"binary\">" +
                              test::base64(header) + test::base64(std::string(10, 'x')) +
                              "</DataArray>\n"
                              "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</"
                              "DataArray>\n" +
                              kVtuTypes);
  text.insert(text.find("type=\"UnstructuredGrid\"") + 23, " compressor=\"vtkZLibDataCompressor\"");
  return text;
}

const Malformed kCases[] = {
    // Gmsh
    {"truncated.msh", kMshHeader + "$Nodes\n4\n1 0 0 0\n2 1 0 0\n",
     "unexpected end of file while reading node tag", 7},
    {"garbage.msh", kMshHeader + "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 zero 0\n", "found 'zero'", 8},
    {"nan.msh", kMshHeader + "$Nodes\n1\n1 0 nan 0\n", "not finite", 6},
    {"repeated-tag.msh", kMshHeader + "$Nodes\n2\n1 0 0 0\n1 1 0 0\n", "appears twice", 7},
    {"missing-node.msh", kMshHeader + kMshNodes + "$Elements\n1\n1 4 0 1 2 3 9\n$EndElements\n",
     "refers to point 9, which is not defined", 13},
    {"repeated-corner.msh", kMshHeader + kMshNodes + "$Elements\n1\n1 4 0 1 2 3 3\n$EndElements\n",
     "uses point 3 twice", 13},
    {"short-count.msh", kMshHeader + kMshNodes + "$Elements\n2\n1 4 0 1 2 3 4\n$EndElements\n",
     "found '$EndElements'", 14},
    {"long-count.msh", kMshHeader + kMshNodes + "$Elements\n1\n1 4 0 1 2 3 4\n2 4 0 1 2 3 4\n",
     "expected '$EndElements', found '2'", 14},
    {"extra-node.msh", kMshHeader + kMshNodes + "$Elements\n1\n1 4 0 1 2 3 4 4\n$EndElements\n",
     "too many nodes", 13},
    {"bad-version.msh", "$MeshFormat\n7.0 0 8\n$EndMeshFormat\n", "unsupported Gmsh format version",
     2},
    {"no-nodes.msh", kMshHeader, "no node section", 0},
    {"binary-truncated.msh", truncated_binary_msh(), "file ends inside binary data", 0},
    {"v4-block-overflow.msh",
     "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 1 2\n3 1 0 3\n1\n2\n3\n",
     "hold more nodes than the 2 announced", 6},
    {"huge-coordinate.msh", kMshHeader + "$Nodes\n1\n1 0 0 1e308\n$EndNodes\n",
     "coordinate of magnitude 1e+308, beyond 1e+30", 6},
    {"huge-block.msh",
     "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2000000000 1 2000000000\n"
     "3 1 0 2000000000\n1\n",
     "nodes in block: 2000000000 values declared, but only 3 bytes are left", 6},
    // TetGen
    {"bad.node", "4 2 0 0\n", "only 3-D .node files", 1},
    {"short.node", "4 3 0 0\n0 0 0 0\n1 1 0 0\n",
     "unexpected end of file while reading point index", 3},
    // MEDIT
    {"unknown.mesh", "MeshVersionFormatted 1\nDimension 3\nVertices\n1\n0 0 0 0\nBananas\n3\n",
     "unknown MEDIT keyword 'Bananas'", 6},
    {"range.mesh",
     "MeshVersionFormatted 1\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n"
     "Tetrahedra\n1\n1 2 3 5 0\nEnd\n",
     "refers to point 5", 11},
    {"no-version.mesh", "Dimension 3\nVertices\n1\n0 0 0 0\nEnd\n", "missing MeshVersionFormatted",
     0},
    // VTK legacy
    {"types.vtk",
     kVtkHead +
         "POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 2\n10\n10\n",
     "CELL_TYPES lists 2 types for 1 cells", 0},
    {"cellsize.vtk",
     kVtkHead + "POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n7 0 1 2 3\nCELL_TYPES 1\n10\n",
     "bad point count 7", 0},
    {"points.vtk", kVtkHead + "POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 x\n", "found 'x'", 6},
    {"keyword.vtk", kVtkHead + "POINTS 1 float\n0 0 0\nWHATEVER 3\n",
     "unexpected keyword 'WHATEVER'", 7},
    {"dataset.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n",
     "only UNSTRUCTURED_GRID and POLYDATA", 4},
    // Counts no file of this size can hold are refused before anything is allocated.
    {"huge-points.vtk", kVtkHead + "POINTS 2147483647 float\n0 0 0 1 0 0 0 1 0 0 0 1\n",
     "point coordinates: 6442450941 values declared, but only 25 bytes are left", 5},
    {"huge-cells.vtk",
     kVtkHead + "POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 2000000000\n4 0 1 2 3\n",
     "CELLS: 2000000000 values declared", 7},
    {"huge-binary.vtk",
     "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 1000000 "
     "float\n\x01\x02\x03\x04",
     "point coordinates: 3000000 values declared, but only 4 bytes are left", 6},
    // VTK XML
    {"xml.vtu", "<VTKFile type=\"UnstructuredGrid\">\n<UnstructuredGrid>\n<Piece>\n</VTKFile>\n",
     "malformed XML", 4},
    {"count.vtu",
     "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece/></UnstructuredGrid></VTKFile>",
     "missing or bad NumberOfPoints", 1},
    {"short-connectivity.vtu",
     vtu_with("<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2</DataArray>\n"
              "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n" +
              kVtuTypes),
     "connectivity: 4 values needed, but the array's text holds at most 3", 8},
    {"range.vtu",
     vtu_with(
         "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 4</DataArray>\n"
         "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n" +
         kVtuTypes),
     "refers to point 4", 0},
    {"base64.vtu",
     vtu_with(
         "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"binary\">AAA*AAAA</DataArray>\n"
         "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n" +
         kVtuTypes),
     "invalid base64 character '*'", 8},
    {"huge-connectivity.vtu",
     vtu_with(
         "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n"
         "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">1000000000</DataArray>\n" +
         kVtuTypes),
     "connectivity: 1000000000 values needed, but the array's text holds at most 4", 8},
    {"zlib-bomb.vtu", zlib_bomb_vtu(), "claims 2147483648 bytes from 10 compressed bytes", 8},
    {"float-ids.vtu",
     vtu_with("<DataArray type=\"Float32\" Name=\"connectivity\" format=\"ascii\">0 1 2 "
              "3e30</DataArray>\n"
              "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n" +
              kVtuTypes),
     "connectivity value 3 (3e+30) is not a point id", 8},
    {"compressor.vtu", "<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkLZ4DataCompressor\"/>",
     "unsupported compressor", 1},
    {"offset.vtu",
     vtu_with(
         "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"appended\" offset=\"99\"/>\n"
         "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n" +
         kVtuTypes) +
         "",
     "missing or bad appended offset", 8},
    {"polydata-type.vtu", "<VTKFile type=\"ImageData\"/>", "holds no tetrahedra or triangles", 1},
    // Surfaces
    {"corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "bad face corner 'x'", 4},
    {"short-face.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", "at least 3 corners", 3},
    {"range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "refers to point 9", 4},
    {"keyword.stl",
     "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvortex 0 1 0\n",
     "expected 'vertex'", 6},
    {"short-binary.stl", std::string(84, 'x') + std::string(10, '\0'),
     "an ASCII STL starts with 'solid'", 1},
    {"format.ply", "ply\nelement vertex 1\nproperty float x\nend_header\n0\n", "no format line", 5},
    {"type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quaternion x\nend_header\n",
     "unknown property type 'quaternion'", 4},
    {"xyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
     "lacks an x, y or z property", 6},
    {"truncated.ply",
     "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n\x01\x02",
     "file ends inside binary data", 0},
    // Anything
    {"empty.dat", "", "unrecognised mesh format", 0},
    {"prose.txt", "This is not a mesh.\n", "unrecognised mesh format", 0},
};

class MalformedInput : public ::testing::TestWithParam<Malformed> {};

TEST_P(MalformedInput, GivesALocatedError) {
  const Malformed& c = GetParam();
  const auto path = test::scratch_dir("malformed") / c.name;
  test::write_file(path, c.content);
  try {
    (void)read_raw_mesh(path);
    FAIL() << "no error for " << c.name;
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(c.message), std::string::npos) << message;
    EXPECT_NE(message.find(c.name), std::string::npos) << "the file is not named: " << message;
    if (c.line > 0) {
      EXPECT_EQ(error.line(), c.line) << message;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllFormats, MalformedInput, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<Malformed>& param_info) {
                           return test::test_name_from(param_info.param.name);
                         });

TEST(MalformedInput, MissingFileAndCompanion) {
  EXPECT_THROW((void)read_raw_mesh("/nonexistent/incise/mesh.msh"), InputError);
  const auto dir = test::scratch_dir("missing-node");
  test::write_file(dir / "lonely.ele", "1 4 0\n0 0 1 2 3\n");
  try {
    (void)read_raw_mesh(dir / "lonely.ele");
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("lonely.node"), std::string::npos) << error.what();
  }
}

TEST(MalformedInput, EveryPrefixOfAValidFileFailsCleanly) {
  // Truncating a valid file anywhere must give an error or a smaller valid result: never a
  // crash, never out-of-range ids.
  const std::string valid =
      kMshHeader + kMshNodes + "$Elements\n2\n1 4 0 1 2 3 4\n2 2 0 1 2 3\n$EndElements\n";
  const auto path = test::scratch_dir("prefixes") / "cut.msh";
  for (std::size_t length = 0; length < valid.size(); ++length) {
    test::write_file(path, valid.substr(0, length));
    try {
      const RawMesh mesh = read_raw_mesh(path);
      for (const Tet& tet : mesh.tets) {
        for (VertexId v : tet) {
          ASSERT_LT(static_cast<std::size_t>(v), mesh.points.size());
        }
      }
    } catch (const InputError&) {
    }
  }
}

}  // namespace
}  // namespace incise
