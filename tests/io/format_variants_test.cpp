// The same small mesh (two tetrahedra sharing a face) written by hand in every supported
// variant of every format: each reader must return exactly that mesh, and say what it skipped.

#include <gtest/gtest.h>

#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "io_test_support.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

const std::vector<Vec3> kPoints = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1),
                                   Vec3(1, 1, 1)};
const std::vector<Tet> kTets = {Tet{0, 1, 2, 3}, Tet{4, 1, 3, 2}};

std::filesystem::path write(const std::string& name, const std::string& bytes) {
  const auto path = test::scratch_dir("format-variants") / name;
  test::write_file(path, bytes);
  return path;
}

void expect_two_tets(const RawMesh& mesh) {
  ASSERT_EQ(mesh.points.size(), kPoints.size());
  for (std::size_t i = 0; i < kPoints.size(); ++i) {
    EXPECT_EQ(mesh.points[i], kPoints[i]) << "point " << i;
  }
  EXPECT_EQ(mesh.tets, kTets);
}

bool has_note(const RawMesh& mesh, const std::string& text) {
  for (const std::string& note : mesh.notes) {
    if (note.find(text) != std::string::npos) {
      return true;
    }
  }
  return false;
}

// ---- Gmsh ------------------------------------------------------------------------------------

TEST(GmshVariants, Version1) {
  const auto mesh = read_raw_mesh(write("v1.msh",
                                        "$NOD\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n"
                                        "$ENDNOD\n$ELM\n4\n1 4 1 1 4 1 2 3 4\n2 4 1 1 4 5 2 4 3\n"
                                        "3 2 1 1 3 1 2 3\n4 1 1 1 2 1 5\n$ENDELM\n"));
  expect_two_tets(mesh);
  EXPECT_EQ(mesh.triangles.size(), 1u);
  EXPECT_TRUE(has_note(mesh, "skipped 1 line elements"));
}

TEST(GmshVariants, Version2AsciiWithTagsAndMixedCells) {
  const auto mesh = read_raw_mesh(
      write("v2.msh",
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"tissue\"\n"
            "$EndPhysicalNames\n$Nodes\n5\n10 0 0 0\n20 1 0 0\n30 0 1 0\n40 0 0 1\n50 1 1 1\n"
            "$EndNodes\n$Elements\n4\n1 4 2 1 1 10 20 30 40\n2 4 3 1 1 0 50 20 40 30\n"
            "3 5 2 1 1 10 20 30 40 50 10 20 30\n4 15 2 1 1 10\n$EndElements\n"));
  expect_two_tets(mesh);
  EXPECT_TRUE(has_note(mesh, "skipped 1 hexahedra"));
  EXPECT_TRUE(has_note(mesh, "skipped 1 point elements"));
}

std::string gmsh2_binary(bool big_endian) {
  std::string bytes = "$MeshFormat\n2.2 1 8\n";
  test::put<std::int32_t>(bytes, 1, big_endian);
  bytes += "\n$EndMeshFormat\n$Nodes\n5\n";
  for (std::size_t i = 0; i < kPoints.size(); ++i) {
    test::put<std::int32_t>(bytes, static_cast<std::int32_t>(i + 1), big_endian);
    for (int k = 0; k < 3; ++k) {
      test::put<double>(bytes, kPoints[i][k], big_endian);
    }
  }
  bytes += "\n$EndNodes\n$Elements\n3\n";
  // Block of two tetrahedra with two tags each, then one triangle.
  for (std::int32_t v : {4, 2, 2}) {
    test::put<std::int32_t>(bytes, v, big_endian);
  }
  for (std::size_t t = 0; t < 2; ++t) {
    test::put<std::int32_t>(bytes, static_cast<std::int32_t>(t + 1), big_endian);
    test::put<std::int32_t>(bytes, 1, big_endian);
    test::put<std::int32_t>(bytes, 1, big_endian);
    for (VertexId v : kTets[t]) {
      test::put<std::int32_t>(bytes, v + 1, big_endian);
    }
  }
  for (std::int32_t v : {2, 1, 0, 3, 1, 2, 3}) {
    test::put<std::int32_t>(bytes, v, big_endian);
  }
  bytes += "\n$EndElements\n";
  return bytes;
}

TEST(GmshVariants, Version2Binary) {
  const auto mesh = read_raw_mesh(write("v2bin.msh", gmsh2_binary(false)));
  expect_two_tets(mesh);
  EXPECT_EQ(mesh.triangles.size(), 1u);
}

TEST(GmshVariants, Version2BinaryOtherEndianness) {
  expect_two_tets(read_raw_mesh(write("v2bin-swapped.msh", gmsh2_binary(true))));
}

TEST(GmshVariants, Version40Ascii) {
  expect_two_tets(read_raw_mesh(
      write("v40.msh",
            "$MeshFormat\n4 0 8\n$EndMeshFormat\n$Nodes\n2 5\n1 3 0 3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n"
            "2 3 0 2\n4 0 0 1\n5 1 1 1\n$EndNodes\n$Elements\n1 2\n1 3 4 2\n1 1 2 3 4\n2 5 2 4 3\n"
            "$EndElements\n")));
}

TEST(GmshVariants, Version41AsciiWithParametricNodes) {
  const auto mesh = read_raw_mesh(
      write("v41.msh",
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 1 1\n1 0 0 0 1 1 1 0 0\n"
            "1 0 0 0 1 1 1 0 0\n$EndEntities\n$Nodes\n2 5 1 5\n2 1 1 3\n1\n2\n3\n0 0 0 0.5 0.5\n"
            "1 0 0 0.1 0.2\n0 1 0 0.3 0.4\n3 1 0 2\n4\n5\n0 0 1\n1 1 1\n$EndNodes\n$Elements\n"
            "2 3 1 3\n2 1 2 1\n3 1 2 3\n3 1 4 2\n1 1 2 3 4\n2 5 2 4 3\n$EndElements\n"));
  expect_two_tets(mesh);
  EXPECT_EQ(mesh.triangles.size(), 1u);
}

TEST(GmshVariants, Version41Binary) {
  std::string bytes = "$MeshFormat\n4.1 1 8\n";
  test::put<std::int32_t>(bytes, 1);
  bytes += "\n$EndMeshFormat\n$Nodes\n";
  for (std::uint64_t v : {1, 5, 1, 5}) {
    test::put<std::uint64_t>(bytes, v);
  }
  test::put<std::int32_t>(bytes, 3);
  test::put<std::int32_t>(bytes, 1);
  test::put<std::int32_t>(bytes, 0);
  test::put<std::uint64_t>(bytes, 5);
  for (std::uint64_t tag = 1; tag <= 5; ++tag) {
    test::put<std::uint64_t>(bytes, tag);
  }
  for (const Vec3& p : kPoints) {
    for (int k = 0; k < 3; ++k) {
      test::put<double>(bytes, p[k]);
    }
  }
  bytes += "\n$EndNodes\n$Elements\n";
  for (std::uint64_t v : {1, 2, 1, 2}) {
    test::put<std::uint64_t>(bytes, v);
  }
  test::put<std::int32_t>(bytes, 3);
  test::put<std::int32_t>(bytes, 1);
  test::put<std::int32_t>(bytes, 4);
  test::put<std::uint64_t>(bytes, 2);
  for (std::size_t t = 0; t < 2; ++t) {
    test::put<std::uint64_t>(bytes, t + 1);
    for (VertexId v : kTets[t]) {
      test::put<std::uint64_t>(bytes, static_cast<std::uint64_t>(v + 1));
    }
  }
  bytes += "\n$EndElements\n";
  expect_two_tets(read_raw_mesh(write("v41bin.msh", bytes)));
}

TEST(GmshVariants, QuadraticTetsKeepCorners) {
  // A 10-node tetrahedron: corners 1-4, mid-edge nodes 5-10.
  std::string text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n10\n";
  const std::vector<Vec3> corners = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  for (int i = 0; i < 4; ++i) {
    text += std::to_string(i + 1) + " " + std::to_string(corners[i].x()) + " " +
            std::to_string(corners[i].y()) + " " + std::to_string(corners[i].z()) + "\n";
  }
  const int edges[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {2, 3}, {1, 3}};
  for (int e = 0; e < 6; ++e) {
    const Vec3 m = 0.5 * (corners[edges[e][0]] + corners[edges[e][1]]);
    text += std::to_string(e + 5) + " " + std::to_string(m.x()) + " " + std::to_string(m.y()) +
            " " + std::to_string(m.z()) + "\n";
  }
  text += "$EndNodes\n$Elements\n1\n1 11 2 0 1 1 2 3 4 5 6 7 8 9 10\n$EndElements\n";
  const auto path = write("tet10.msh", text);
  const TetMeshReadResult read = read_tet_mesh(path);
  EXPECT_EQ(read.mesh.tet_count(), 1u);
  EXPECT_EQ(read.mesh.vertex_count(), 4u);
  EXPECT_EQ(read.dropped_vertices, 6u);
  EXPECT_NEAR(total_volume(read.mesh), 1.0 / 6.0, 1e-15);
}

// ---- TetGen and MEDIT --------------------------------------------------------------------------

TEST(TetGenVariants, OneBasedWithAttributesMarkersAndComments) {
  write("one.node",
        "# points\n5 3 1 1\n1 0 0 0 7.5 1\n2 1 0 0 7.5 1\n3 0 1 0 7.5 0\n4 0 0 1 7.5 0\n"
        "5 1 1 1 7.5 1 # last\n");
  const auto mesh = read_raw_mesh(write("one.ele", "2 4 1\n1 1 2 3 4 -1\n2 5 2 4 3 -1\n"));
  expect_two_tets(mesh);
}

TEST(TetGenVariants, NodeFileAloneHasNoTets) {
  const auto path = write("alone.node", "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 1\n");
  EXPECT_EQ(read_raw_mesh(path).points.size(), 5u);
  EXPECT_THROW((void)read_tet_mesh(path), InputError);
}

TEST(MeditVariants, SkippedSectionsAndComments) {
  const auto mesh = read_raw_mesh(
      write("two.mesh",
            "MeshVersionFormatted 2\n# a comment\nDimension\n3\nVertices\n5\n0 0 0 1\n1 0 0 1\n"
            "0 1 0 1\n0 0 1 1\n1 1 1 1\nEdges\n1\n1 2 0\nCorners\n2\n1 2\nTetrahedra\n2\n"
            "1 2 3 4 1\n5 2 4 3 2\nTriangles\n1\n1 2 3 0\nEnd\n"));
  expect_two_tets(mesh);
  EXPECT_EQ(mesh.triangles.size(), 1u);
  EXPECT_TRUE(has_note(mesh, "skipped 1 edges"));
  EXPECT_TRUE(has_note(mesh, "skipped 2 corners"));
}

// ---- OFF ---------------------------------------------------------------------------------------

TEST(OffVariants, QuadsCommentsColoursAndDetectionByContent) {
  // A unit cube of quads (one with a face colour), with a comment; read by extension and,
  // renamed, by its first word. Quads are split, and the note says so (not "skipped").
  const std::string cube =
      "OFF\n# a cube\n8 6 12\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
      "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7 255 0 0\n";
  for (const char* name : {"cube.off", "cube.surface"}) {
    const RawMesh mesh = read_raw_mesh(write(name, cube));
    EXPECT_EQ(mesh.format, MeshFormat::kOff) << name;
    EXPECT_EQ(mesh.points.size(), 8u);
    EXPECT_EQ(mesh.triangles.size(), 12u);
    EXPECT_TRUE(has_note(mesh, "split 6 polygons with more than 3 corners into triangles"));
  }
  // Vertex colours (COFF) are skipped with the rest of their line.
  const RawMesh coloured =
      read_raw_mesh(write("tri.off",
                          "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n"
                          "3 0 1 2\n"));
  EXPECT_EQ(coloured.triangles.size(), 1u);
  EXPECT_DOUBLE_EQ(coloured.points[1].x(), 1.0);
  // A face corner past the vertices is an error naming the line.
  try {
    (void)read_raw_mesh(write("bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"));
    ADD_FAILURE() << "a corner past the vertices was accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find(":6"), std::string::npos) << error.what();
  }
}

TEST(ObjVariants, QuadsAreSplitAndTheNoteSaysSo) {
  const RawMesh mesh =
      read_raw_mesh(write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"));
  EXPECT_EQ(mesh.triangles.size(), 2u);
  EXPECT_TRUE(has_note(mesh, "split 1 polygons with more than 3 corners into triangles"));
  for (const std::string& note : mesh.notes) {
    EXPECT_EQ(note.find("skipped"), std::string::npos) << note;
  }
}

// ---- VTK legacy --------------------------------------------------------------------------------

const char* kVtkPoints = "POINTS 5 double\n0 0 0 1 0 0 0 1 0\n0 0 1 1 1 1\n";

TEST(VtkLegacyVariants, AsciiUnstructuredGridWithMixedCells) {
  const auto mesh = read_raw_mesh(
      write("ascii.vtk",
            std::string("# vtk DataFile Version 3.0\ntest\nASCII\nDATASET UNSTRUCTURED_GRID\n") +
                kVtkPoints +
                "CELLS 4 20\n4 0 1 2 3\n4 4 1 3 2\n3 0 1 2\n5 0 1 2 3 4\n"
                "CELL_TYPES 4\n10\n10\n5\n7\nPOINT_DATA 5\nSCALARS s float 1\n"
                "LOOKUP_TABLE default\n1 2 3 4 5\n"));
  expect_two_tets(mesh);
  EXPECT_EQ(mesh.triangles.size(), 1u);
  EXPECT_TRUE(has_note(mesh, "skipped 1 polygons"));
}

TEST(VtkLegacyVariants, FieldDataBeforePoints) {
  // As ParaView writes it: TIME and CYCLE in a FIELD block right after DATASET.
  const auto mesh = read_raw_mesh(write(
      "field.vtk",
      std::string("# vtk DataFile Version 4.2\nparaview\nASCII\nDATASET UNSTRUCTURED_GRID\n") +
          "FIELD FieldData 2\nTIME 1 1 double\n0.5\nCYCLE 1 1 int\n3\n" + kVtkPoints +
          "CELLS 2 10\n4 0 1 2 3\n4 4 1 3 2\nCELL_TYPES 2\n10\n10\n"
          "CELL_DATA 2\nFIELD FieldData 1\nids 1 2 int\n0 1\n"));
  expect_two_tets(mesh);
}

TEST(VtkLegacyVariants, Version51OffsetsLayout) {
  const auto mesh = read_raw_mesh(
      write("v51.vtk",
            std::string("# vtk DataFile Version 5.1\ntest\nASCII\nDATASET UNSTRUCTURED_GRID\n") +
                kVtkPoints +
                "METADATA\nINFORMATION 0\n\nCELLS 3 8\nOFFSETS vtktypeint64\n0 4 8\n"
                "CONNECTIVITY vtktypeint64\n0 1 2 3 4 1 3 2\nCELL_TYPES 2\n10\n10\n"));
  expect_two_tets(mesh);
}

TEST(VtkLegacyVariants, BinaryUnstructuredGrid) {
  std::string bytes =
      "# vtk DataFile Version 3.0\nbinary\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n";
  for (const Vec3& p : kPoints) {
    for (int k = 0; k < 3; ++k) {
      test::put<float>(bytes, static_cast<float>(p[k]), true);
    }
  }
  bytes += "\nCELLS 2 10\n";
  for (const Tet& tet : kTets) {
    test::put<std::int32_t>(bytes, 4, true);
    for (VertexId v : tet) {
      test::put<std::int32_t>(bytes, v, true);
    }
  }
  bytes += "\nCELL_TYPES 2\n";
  test::put<std::int32_t>(bytes, 10, true);
  test::put<std::int32_t>(bytes, 10, true);
  bytes += "\n";
  expect_two_tets(read_raw_mesh(write("binary.vtk", bytes)));
}

TEST(VtkLegacyVariants, PolydataPolygonsAndStrips) {
  const auto mesh = read_raw_mesh(write(
      "poly.vtk", std::string("# vtk DataFile Version 2.0\nsurface\nASCII\nDATASET POLYDATA\n") +
                      kVtkPoints +
                      "POLYGONS 2 9\n3 0 2 1\n4 0 1 4 2\nTRIANGLE_STRIPS 1 5\n4 0 1 3 4\n"));
  EXPECT_EQ(mesh.points.size(), 5u);
  // 1 triangle + a quad split in 2 + a 4-point strip giving 2 triangles.
  ASSERT_EQ(mesh.triangles.size(), 5u);
  EXPECT_EQ(mesh.triangles[3], (Triangle{0, 1, 3}));
  EXPECT_EQ(mesh.triangles[4], (Triangle{3, 1, 4}));  // flipped to keep the orientation
}

// ---- VTK XML -----------------------------------------------------------------------------------

/// Raw bytes of the test mesh's arrays.
struct VtuArrays {
  std::string points;
  std::string connectivity;
  std::string offsets;
  std::string types;
};

VtuArrays vtu_arrays(bool big_endian) {
  VtuArrays arrays;
  for (const Vec3& p : kPoints) {
    for (int k = 0; k < 3; ++k) {
      test::put<float>(arrays.points, static_cast<float>(p[k]), big_endian);
    }
  }
  for (const Tet& tet : kTets) {
    for (VertexId v : tet) {
      test::put<std::int64_t>(arrays.connectivity, v, big_endian);
    }
  }
  test::put<std::int64_t>(arrays.offsets, 4, big_endian);
  test::put<std::int64_t>(arrays.offsets, 8, big_endian);
  arrays.types = std::string("\x0a\x0a", 2);
  return arrays;
}

std::string vtu_document(const std::string& attributes, const std::string& points,
                         const std::string& connectivity, const std::string& offsets,
                         const std::string& types, const std::string& appended = "") {
  return "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" " +
         attributes +
         ">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"5\" NumberOfCells=\"2\">\n<Points>\n" +
         points + "\n</Points>\n<Cells>\n" + connectivity + "\n" + offsets + "\n" + types +
         "\n</Cells>\n</Piece>\n</UnstructuredGrid>\n" + appended + "</VTKFile>\n";
}

TEST(VtkXmlVariants, Ascii) {
  const auto mesh = read_raw_mesh(write(
      "ascii.vtu",
      vtu_document(
          "byte_order=\"LittleEndian\"",
          "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 "
          "0 0 1 1 1 1</DataArray>",
          "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3 4 1 3 "
          "2</DataArray>",
          "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4 8</DataArray>",
          "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10 10</DataArray>")));
  expect_two_tets(mesh);
}

/// Inline base64 with the header encoded separately (as VTK writes it).
std::string inline_array(const std::string& attributes, const std::string& data, bool uint64,
                         bool compress, bool big_endian) {
  std::string header;
  std::string payload = data;
  if (compress) {
    payload = test::zlib_compress(data);
    for (std::uint64_t v : {std::uint64_t{1}, std::uint64_t{data.size()},
                            std::uint64_t{data.size()}, std::uint64_t{payload.size()}}) {
      uint64 ? test::put<std::uint64_t>(header, v, big_endian)
             : test::put<std::uint32_t>(header, static_cast<std::uint32_t>(v), big_endian);
    }
  } else {
    uint64 ? test::put<std::uint64_t>(header, data.size(), big_endian)
           : test::put<std::uint32_t>(header, static_cast<std::uint32_t>(data.size()), big_endian);
  }
  return "<DataArray " + attributes + " format=\"binary\">\n  " + test::base64(header) +
         test::base64(payload) + "\n</DataArray>";
}

class VtuInlineBinary : public ::testing::TestWithParam<std::tuple<bool, bool, bool>> {};

TEST_P(VtuInlineBinary, Decodes) {
  const auto [uint64, compress, big_endian] = GetParam();
  const VtuArrays a = vtu_arrays(big_endian);
  std::string attributes = std::string("byte_order=\"") +
                           (big_endian ? "BigEndian" : "LittleEndian") + "\" header_type=\"" +
                           (uint64 ? "UInt64" : "UInt32") + "\"";
  if (compress) {
    attributes += " compressor=\"vtkZLibDataCompressor\"";
  }
  const std::string document = vtu_document(
      attributes,
      inline_array("type=\"Float32\" NumberOfComponents=\"3\"", a.points, uint64, compress,
                   big_endian),
      inline_array("type=\"Int64\" Name=\"connectivity\"", a.connectivity, uint64, compress,
                   big_endian),
      inline_array("type=\"Int64\" Name=\"offsets\"", a.offsets, uint64, compress, big_endian),
      inline_array("type=\"UInt8\" Name=\"types\"", a.types, uint64, compress, big_endian));
  expect_two_tets(read_raw_mesh(write("inline.vtu", document)));
}

INSTANTIATE_TEST_SUITE_P(HeaderCompressionByteOrder, VtuInlineBinary,
                         ::testing::Combine(::testing::Bool(), ::testing::Bool(),
                                            ::testing::Bool()));

TEST(VtkXmlVariants, InlineBase64EncodedTogether) {
  // Some writers encode header and data as one base64 stream.
  const VtuArrays a = vtu_arrays(false);
  auto joint = [](const std::string& attributes, const std::string& data) {
    std::string bytes;
    test::put<std::uint32_t>(bytes, static_cast<std::uint32_t>(data.size()));
    return "<DataArray " + attributes + " format=\"binary\">" + test::base64(bytes + data) +
           "</DataArray>";
  };
  const std::string document = vtu_document(
      "byte_order=\"LittleEndian\"", joint("type=\"Float32\" NumberOfComponents=\"3\"", a.points),
      joint("type=\"Int64\" Name=\"connectivity\"", a.connectivity),
      joint("type=\"Int64\" Name=\"offsets\"", a.offsets),
      joint("type=\"UInt8\" Name=\"types\"", a.types));
  expect_two_tets(read_raw_mesh(write("joint.vtu", document)));
}

class VtuAppended : public ::testing::TestWithParam<std::tuple<bool, bool>> {};

TEST_P(VtuAppended, Decodes) {
  const bool encode_base64 = std::get<0>(GetParam());  // not a structured binding: clang 14
  const bool compress = std::get<1>(GetParam());       // cannot capture those in lambdas
  const VtuArrays a = vtu_arrays(false);
  std::string appended;
  auto array = [&](const std::string& attributes, const std::string& data) {
    std::string block;
    std::string payload = compress ? test::zlib_compress(data) : data;
    std::string header;
    if (compress) {
      for (std::uint64_t v : {std::uint64_t{1}, std::uint64_t{data.size()},
                              std::uint64_t{data.size()}, std::uint64_t{payload.size()}}) {
        test::put<std::uint64_t>(header, v);
      }
    } else {
      test::put<std::uint64_t>(header, data.size());
    }
    block = encode_base64 ? test::base64(header) + test::base64(payload) : header + payload;
    const std::string xml = "<DataArray " + attributes + " format=\"appended\" offset=\"" +
                            std::to_string(appended.size()) + "\"/>";
    appended += block;
    return xml;
  };
  std::string attributes = "byte_order=\"LittleEndian\" header_type=\"UInt64\"";
  if (compress) {
    attributes += " compressor=\"vtkZLibDataCompressor\"";
  }
  const std::string points = array("type=\"Float32\" NumberOfComponents=\"3\"", a.points);
  const std::string connectivity = array("type=\"Int64\" Name=\"connectivity\"", a.connectivity);
  const std::string offsets = array("type=\"Int64\" Name=\"offsets\"", a.offsets);
  const std::string types = array("type=\"UInt8\" Name=\"types\"", a.types);
  const std::string document =
      vtu_document(attributes, points, connectivity, offsets, types,
                   std::string("<AppendedData encoding=\"") + (encode_base64 ? "base64" : "raw") +
                       "\">\n_" + appended + "\n</AppendedData>\n");
  expect_two_tets(read_raw_mesh(write("appended.vtu", document)));
}

INSTANTIATE_TEST_SUITE_P(EncodingCompression, VtuAppended,
                         ::testing::Combine(::testing::Bool(), ::testing::Bool()));

TEST(VtkXmlVariants, MultiplePiecesAndMixedCells) {
  const std::string piece =
      "<Piece NumberOfPoints=\"4\" NumberOfCells=\"2\"><Points><DataArray type=\"Float64\" "
      "NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>"
      "<Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3 0 1 "
      "2</DataArray><DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4 "
      "7</DataArray><DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10 "
      "5</DataArray></Cells></Piece>";
  const auto mesh =
      read_raw_mesh(write("pieces.vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>" +
                                            piece + piece + "</UnstructuredGrid></VTKFile>"));
  ASSERT_EQ(mesh.points.size(), 8u);
  ASSERT_EQ(mesh.tets.size(), 2u);
  EXPECT_EQ(mesh.tets[1], (Tet{4, 5, 6, 7}));
  EXPECT_EQ(mesh.triangles.size(), 2u);
}

// ---- surfaces ----------------------------------------------------------------------------------

TEST(SurfaceVariants, ObjPolygonsNegativeIndicesAndTextureCoordinates) {
  const auto surface = read_surface(write("quad.obj",
                                          "# a unit square and a triangle\nmtllib none.mtl\no sq\n"
                                          "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
                                          "f 1/1/1 2/1/1 3/1/1 4/1/1\nv 0 0 1\nf -1 -5 -4\n"));
  EXPECT_EQ(surface.points.size(), 5u);
  ASSERT_EQ(surface.triangles.size(), 3u);
  EXPECT_EQ(surface.triangles[2], (Triangle{4, 0, 1}));  // -1 is the fifth vertex
}

TEST(SurfaceVariants, StlAsciiAndBinaryWeldCorners) {
  const auto ascii = read_surface(
      write("tet.stl",
            "solid t\nfacet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\n"
            "endloop\nendfacet\nfacet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
            "vertex 0 0 1\nendloop\nendfacet\nfacet normal -1 0 0\nouter loop\nvertex 0 0 0\n"
            "vertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\nfacet normal 1 1 1\nouter loop\n"
            "vertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid t\n"));
  EXPECT_EQ(ascii.points.size(), 4u);
  EXPECT_EQ(ascii.triangles.size(), 4u);
  // Binary, with a header that starts with "solid" (as many exporters write).
  std::string bytes = "solid binary-but-says-solid";
  bytes.resize(80, ' ');
  test::put<std::uint32_t>(bytes, 4);
  const float corners[4][9] = {{0, 0, 0, 0, 1, 0, 1, 0, 0},
                               {0, 0, 0, 1, 0, 0, 0, 0, 1},
                               {0, 0, 0, 0, 0, 1, 0, 1, 0},
                               {1, 0, 0, 0, 1, 0, 0, 0, 1}};
  for (const auto& triangle : corners) {
    for (int k = 0; k < 3; ++k) {
      test::put<float>(bytes, 0.0F);
    }
    for (float c : triangle) {
      test::put<float>(bytes, c);
    }
    test::put<std::uint16_t>(bytes, 0);
  }
  const auto binary = read_surface(write("tet-binary.stl", bytes));
  EXPECT_EQ(binary.points.size(), 4u);
  EXPECT_EQ(binary.triangles, ascii.triangles);
}

std::string ply_binary(bool big_endian) {
  std::string bytes = std::string("ply\nformat ") +
                      (big_endian ? "binary_big_endian" : "binary_little_endian") +
                      " 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty double y\n"
                      "property float z\nproperty uchar red\nelement face 2\n"
                      "property list uchar int vertex_indices\nelement edge 1\n"
                      "property int vertex1\nproperty int vertex2\nend_header\n";
  const double points[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (const auto& p : points) {
    test::put<float>(bytes, static_cast<float>(p[0]), big_endian);
    test::put<double>(bytes, p[1], big_endian);
    test::put<float>(bytes, static_cast<float>(p[2]), big_endian);
    test::put<std::uint8_t>(bytes, 200, big_endian);
  }
  test::put<std::uint8_t>(bytes, 4, big_endian);
  for (std::int32_t v : {0, 1, 2, 3}) {
    test::put<std::int32_t>(bytes, v, big_endian);
  }
  test::put<std::uint8_t>(bytes, 3, big_endian);
  for (std::int32_t v : {0, 2, 1}) {
    test::put<std::int32_t>(bytes, v, big_endian);
  }
  test::put<std::int32_t>(bytes, 0, big_endian);
  test::put<std::int32_t>(bytes, 1, big_endian);
  return bytes;
}

TEST(SurfaceVariants, PlyAsciiAndBinary) {
  const auto ascii =
      read_surface(write("square.ply",
                         "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                         "property float y\nproperty float z\nelement face 2\n"
                         "property list uchar int vertex_index\nend_header\n"
                         "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n3 0 2 1\n"));
  ASSERT_EQ(ascii.triangles.size(), 3u);
  EXPECT_EQ(ascii.points[2], Vec3(1, 1, 0));
  for (bool big_endian : {false, true}) {
    const auto binary =
        read_surface(write(big_endian ? "be.ply" : "le.ply", ply_binary(big_endian)));
    EXPECT_EQ(binary.triangles, ascii.triangles);
    EXPECT_EQ(binary.points, ascii.points);
    EXPECT_FALSE(binary.notes.empty());  // the edge element was skipped, and said so
  }
}

}  // namespace
}  // namespace incise
