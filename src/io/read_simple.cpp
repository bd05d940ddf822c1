// Readers for the line-oriented formats: TetGen .node/.ele, MEDIT .mesh, OBJ, STL and PLY.
// Each is short; the Debian parsers for them (tinyobjloader, assimp) accept garbage numbers
// silently or renumber vertices, and cannot name the failing line.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <unordered_map>

#include "readers.hpp"

namespace incise::io_detail {

// ---- TetGen -------------------------------------------------------------------------------

RawMesh read_tetgen(Source& node_source, Source* ele_source) {
  node_source.set_comment_char('#');
  MeshBuilder builder(node_source);
  const std::size_t count = node_source.count("point count", kMaxCount);
  const long long dimension = node_source.integer("dimension");
  if (dimension != 3) {
    node_source.fail("only 3-D .node files are supported (dimension " + std::to_string(dimension) +
                     ")");
  }
  const std::size_t attributes = node_source.count("attribute count", 1000);
  const std::size_t markers = node_source.count("boundary marker flag", 1);
  for (std::size_t i = 0; i < count; ++i) {
    // Points are referred to by their index, whether the file counts from 0 or 1.
    const long long index = node_source.integer("point index");
    const double x = node_source.real("x");
    const double y = node_source.real("y");
    const double z = node_source.real("z");
    for (std::size_t a = 0; a < attributes; ++a) {
      (void)node_source.real("point attribute");
    }
    for (std::size_t m = 0; m < markers; ++m) {
      (void)node_source.integer("boundary marker");
    }
    builder.add_point(index, Vec3(x, y, z));
  }
  if (!node_source.next_token().empty()) {
    node_source.fail("more points than the " + std::to_string(count) + " announced");
  }
  if (ele_source == nullptr) {
    return builder.finish(MeshFormat::kTetGen);
  }
  Source& ele = *ele_source;
  ele.set_comment_char('#');
  builder.set_source(ele);
  const std::size_t tet_count = ele.count("tetrahedron count", kMaxCount);
  const long long corners = ele.integer("nodes per tetrahedron");
  if (corners != 4 && corners != 10) {
    ele.fail("nodes per tetrahedron must be 4 or 10, found " + std::to_string(corners));
  }
  const std::size_t region_attributes = ele.count("region attribute flag", 1);
  for (std::size_t i = 0; i < tet_count; ++i) {
    (void)ele.integer("tetrahedron index");
    std::array<long long, 4> nodes{};
    for (long long& node : nodes) {
      node = ele.integer("tetrahedron corner");
    }
    for (long long extra = 4; extra < corners; ++extra) {
      (void)ele.integer("mid-edge node");
    }
    // TetGen's region attribute (-A) is a number; regions are numbered by integers.
    long long label = 0;
    for (std::size_t a = 0; a < region_attributes; ++a) {
      const double attribute = ele.real("region attribute");
      if (attribute != std::floor(attribute) || std::abs(attribute) > 2e9) {
        ele.fail("region attribute " + std::to_string(attribute) + " is not an integer label");
      }
      label = static_cast<long long>(attribute);
    }
    if (ele.token_on_this_line()) {
      ele.fail("too many values on a tetrahedron line");
    }
    builder.add_tet(nodes, label);
  }
  if (!ele.next_token().empty()) {
    ele.fail("more tetrahedra than the " + std::to_string(tet_count) + " announced");
  }
  if (corners == 10) {
    builder.skip("mid-edge nodes (kept the corners of quadratic tetrahedra)", tet_count * 6);
  }
  return builder.finish(MeshFormat::kTetGen);
}

// ---- MEDIT --------------------------------------------------------------------------------

RawMesh read_medit(Source& source) {
  source.set_comment_char('#');
  MeshBuilder builder(source);
  builder.set_implicit_tags(1);
  // Sections we skip, with the number of values per entry (3-D files).
  static const std::map<std::string, int> kSkipped = {{"edges", 3},
                                                      {"quadrilaterals", 5},
                                                      {"hexahedra", 9},
                                                      {"prisms", 7},
                                                      {"pyramids", 6},
                                                      {"corners", 1},
                                                      {"ridges", 1},
                                                      {"requiredvertices", 1},
                                                      {"requirededges", 1},
                                                      {"requiredtriangles", 1},
                                                      {"normals", 3},
                                                      {"tangents", 3},
                                                      {"normalatvertices", 2},
                                                      {"tangentatedges", 3},
                                                      {"normalattrianglevertices", 3},
                                                      {"tetrahedrap2", 11},
                                                      {"trianglesp2", 7},
                                                      {"edgesp2", 4},
                                                      {"requiredtetrahedra", 1},
                                                      {"requiredquadrilaterals", 1}};
  bool saw_version = false;
  for (;;) {
    const std::string_view keyword_token = source.next_token();
    if (keyword_token.empty()) {
      break;
    }
    const std::string keyword = lowercase(keyword_token);
    if (keyword == "end") {
      break;
    }
    if (keyword == "meshversionformatted") {
      const long long version = source.integer("mesh version");
      if (version < 1 || version > 4) {
        source.fail("unsupported MEDIT version " + std::to_string(version));
      }
      saw_version = true;
    } else if (keyword == "dimension") {
      const long long dimension = source.integer("dimension");
      if (dimension != 3) {
        source.fail("only 3-D MEDIT meshes are supported (Dimension " + std::to_string(dimension) +
                    ")");
      }
    } else if (keyword == "vertices") {
      if (builder.point_count() > 0) {
        source.fail("a second Vertices section");
      }
      const std::size_t count = source.count("vertex count", kMaxCount);
      for (std::size_t i = 0; i < count; ++i) {
        const double x = source.real("x");
        const double y = source.real("y");
        const double z = source.real("z");
        (void)source.integer("vertex reference");
        builder.add_point(static_cast<long long>(i) + 1, Vec3(x, y, z));
      }
    } else if (keyword == "tetrahedra") {
      const std::size_t count = source.count("tetrahedron count", kMaxCount);
      for (std::size_t i = 0; i < count; ++i) {
        std::array<long long, 4> nodes{};
        for (long long& node : nodes) {
          node = source.integer("tetrahedron vertex");
        }
        builder.add_tet(nodes, source.integer("tetrahedron reference"));
      }
    } else if (keyword == "triangles") {
      const std::size_t count = source.count("triangle count", kMaxCount);
      for (std::size_t i = 0; i < count; ++i) {
        std::array<long long, 3> nodes{};
        for (long long& node : nodes) {
          node = source.integer("triangle vertex");
        }
        (void)source.integer("triangle reference");
        builder.add_triangle(nodes);
      }
    } else if (const auto skipped = kSkipped.find(keyword); skipped != kSkipped.end()) {
      const std::size_t count = source.count("entry count", kMaxCount);
      for (std::size_t i = 0; i < count * static_cast<std::size_t>(skipped->second); ++i) {
        (void)source.token("section entries");
      }
      builder.skip(keyword, count);
    } else {
      source.fail("unknown MEDIT keyword '" + std::string(keyword_token) + "'");
    }
  }
  if (!saw_version) {
    source.fail_without_line("missing MeshVersionFormatted");
  }
  return builder.finish(MeshFormat::kMedit);
}

// ---- OBJ ----------------------------------------------------------------------------------

RawMesh read_obj(Source& source) {
  source.set_comment_char('#');
  MeshBuilder builder(source);
  builder.set_implicit_tags(1);
  std::size_t polygons = 0;
  std::vector<long long> corners;
  while (!source.at_end()) {
    const std::string_view keyword = source.next_token();
    if (keyword.empty()) {
      break;
    }
    if (keyword == "v") {
      const double x = source.real("x");
      const double y = source.real("y");
      const double z = source.real("z");
      builder.add_point(static_cast<long long>(builder.point_count()) + 1, Vec3(x, y, z));
      source.skip_line();  // optional w or colour
    } else if (keyword == "f") {
      corners.clear();
      while (source.token_on_this_line()) {
        const std::string_view corner = source.next_token();
        // v, v/vt, v//vn or v/vt/vn: the position index comes first.
        const std::string_view position = corner.substr(0, corner.find('/'));
        long long index = 0;
        if (!parse_integer(position, index) || index == 0) {
          source.fail("bad face corner '" + std::string(corner) + "'");
        }
        if (index < 0) {  // relative to the last vertex read
          index += static_cast<long long>(builder.point_count()) + 1;
        }
        corners.push_back(index);
      }
      if (corners.size() < 3) {
        source.fail("a face needs at least 3 corners, found " + std::to_string(corners.size()));
      }
      polygons += corners.size() > 3 ? 1 : 0;
      for (std::size_t i = 1; i + 1 < corners.size(); ++i) {
        builder.add_triangle({corners[0], corners[i], corners[i + 1]});
      }
      source.skip_line();
    } else {
      if (keyword == "l" || keyword == "p") {
        builder.skip(keyword == "l" ? "line elements" : "point elements");
      }
      source.skip_line();  // vt, vn, g, o, s, usemtl, mtllib, ...
    }
  }
  RawMesh raw = builder.finish(MeshFormat::kObj);
  if (polygons > 0) {
    raw.notes.push_back("split " + std::to_string(polygons) +
                        " polygons with more than 3 corners into triangles");
  }
  return raw;
}

// ---- OFF (Object File Format: Geomview, CGAL, Meshlab) ------------------------------------

RawMesh read_off(Source& source) {
  source.set_comment_char('#');
  MeshBuilder builder(source);
  builder.set_implicit_tags(0);
  // The header keyword names what each vertex carries besides x y z (ST: texture, C: colour,
  // N: normal, 4: a fourth coordinate); the extras are skipped with the rest of the line.
  const std::string keyword(source.token("the OFF keyword"));
  if (keyword.size() < 3 || keyword.substr(keyword.size() - 3) != "OFF" ||
      keyword.find_first_not_of("STCN4") < keyword.size() - 3) {
    source.fail("not an OFF file: the first word is '" + keyword + "', not OFF");
  }
  if (keyword.find('4') != std::string::npos) {
    source.fail("4OFF (four coordinates per vertex) is not a 3-D surface");
  }
  constexpr std::size_t kLimit = std::size_t{1} << 31;
  const std::size_t vertices = source.count("the vertex count", kLimit);
  const std::size_t faces = source.count("the face count", kLimit);
  (void)source.count("the edge count", kLimit);
  source.require_room(3 * vertices + 4 * faces, 0, "the vertices and faces");
  for (std::size_t i = 0; i < vertices; ++i) {
    const double x = source.real("x");
    const double y = source.real("y");
    const double z = source.real("z");
    builder.add_point(static_cast<long long>(i), Vec3(x, y, z));
    source.skip_line();  // colour, normal, texture coordinates
  }
  std::size_t polygons = 0;
  for (std::size_t f = 0; f < faces; ++f) {
    const std::size_t corners = source.count("a face's corner count", vertices + 1);
    if (corners < 3) {
      if (corners > 0) {
        builder.skip(corners == 1 ? "point elements" : "line elements");
      }
      source.skip_line();
      continue;
    }
    std::vector<long long> ids(corners);
    for (long long& id : ids) {
      id = source.integer("a face corner");
    }
    polygons += corners > 3 ? 1 : 0;
    for (std::size_t i = 1; i + 1 < corners; ++i) {
      builder.add_triangle({ids[0], ids[i], ids[i + 1]});
    }
    source.skip_line();  // a colour
  }
  RawMesh raw = builder.finish(MeshFormat::kOff);
  if (polygons > 0) {
    raw.notes.push_back("split " + std::to_string(polygons) +
                        " polygons with more than 3 corners into triangles");
  }
  return raw;
}

// ---- STL ----------------------------------------------------------------------------------

namespace {

/// STL repeats every corner; merge exactly equal coordinates into one point.
class PointWelder {
 public:
  explicit PointWelder(MeshBuilder& builder) : builder_(builder) {}
  long long add(const Vec3& p) {
    std::array<double, 3> key{p.x() == 0.0 ? 0.0 : p.x(), p.y() == 0.0 ? 0.0 : p.y(),
                              p.z() == 0.0 ? 0.0 : p.z()};  // -0 == +0
    const auto [it, inserted] =
        index_.try_emplace(key, static_cast<long long>(builder_.point_count()));
    if (inserted) {
      builder_.add_point(it->second, p);
    }
    return it->second;
  }

 private:
  MeshBuilder& builder_;
  std::map<std::array<double, 3>, long long> index_;
};

bool stl_is_binary(std::string_view bytes) {
  if (bytes.size() < 84) {
    return false;
  }
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  if (!kHostIsLittleEndian) {
    count = Source::byte_swapped(count);
  }
  return 84 + 50ULL * count == bytes.size();
}

}  // namespace

RawMesh read_stl(Source& source) {
  MeshBuilder builder(source);
  PointWelder welder(builder);
  if (stl_is_binary(source.bytes())) {
    source.seek(80);
    const auto count = source.binary<std::uint32_t>(!kHostIsLittleEndian, "triangle count");
    for (std::uint32_t t = 0; t < count; ++t) {
      float values[12];
      for (float& value : values) {
        value = source.binary<float>(!kHostIsLittleEndian, "triangle");
      }
      (void)source.binary<std::uint16_t>(!kHostIsLittleEndian, "attribute byte count");
      std::array<long long, 3> corners{};
      for (int c = 0; c < 3; ++c) {
        const Vec3 p(values[3 + 3 * c], values[4 + 3 * c], values[5 + 3 * c]);
        if (!p.allFinite()) {
          source.fail_without_line("triangle " + std::to_string(t) + " has a non-finite corner");
        }
        corners[c] = welder.add(p);
      }
      builder.add_triangle(corners);
    }
    return builder.finish(MeshFormat::kStl);
  }
  const std::string first = lowercase(source.token("'solid'"));
  if (first != "solid") {
    source.fail("an ASCII STL starts with 'solid' (and a binary one's size is 84 + 50 n bytes)");
  }
  source.skip_line();
  for (;;) {
    const std::string keyword = lowercase(source.token("'facet' or 'endsolid'"));
    if (keyword == "endsolid") {
      break;
    }
    if (keyword != "facet") {
      source.fail("expected 'facet' or 'endsolid', found '" + keyword + "'");
    }
    source.skip_line();  // normal: recomputed from the corners when needed
    if (lowercase(source.token("'outer loop'")) != "outer" ||
        lowercase(source.token("'loop'")) != "loop") {
      source.fail("expected 'outer loop'");
    }
    std::array<long long, 3> corners{};
    for (long long& corner : corners) {
      if (lowercase(source.token("'vertex'")) != "vertex") {
        source.fail("expected 'vertex'");
      }
      const double x = source.real("x");
      const double y = source.real("y");
      const double z = source.real("z");
      corner = welder.add(Vec3(x, y, z));
    }
    if (lowercase(source.token("'endloop'")) != "endloop") {
      source.fail("expected 'endloop' (only triangles are allowed)");
    }
    if (lowercase(source.token("'endfacet'")) != "endfacet") {
      source.fail("expected 'endfacet'");
    }
    builder.add_triangle(corners);
  }
  return builder.finish(MeshFormat::kStl);
}

// ---- PLY ----------------------------------------------------------------------------------

namespace {

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

bool ply_type(std::string_view name, PlyType& type) {
  static const std::map<std::string, PlyType, std::less<>> kTypes = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16},  {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  const auto it = kTypes.find(name);
  if (it == kTypes.end()) {
    return false;
  }
  type = it->second;
  return true;
}

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;
  PlyType type = PlyType::kFloat32;
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;
};

double read_ply_value(Source& source, int format, PlyType type, const char* what) {
  if (format == 0) {
    return type == PlyType::kFloat32 || type == PlyType::kFloat64
               ? source.real(what)
               : static_cast<double>(source.integer(what));
  }
  const bool swap = (format == 1) != kHostIsLittleEndian;
  switch (type) {
    case PlyType::kInt8:
      return source.binary<std::int8_t>(swap, what);
    case PlyType::kUint8:
      return source.binary<std::uint8_t>(swap, what);
    case PlyType::kInt16:
      return source.binary<std::int16_t>(swap, what);
    case PlyType::kUint16:
      return source.binary<std::uint16_t>(swap, what);
    case PlyType::kInt32:
      return source.binary<std::int32_t>(swap, what);
    case PlyType::kUint32:
      return source.binary<std::uint32_t>(swap, what);
    case PlyType::kFloat32:
      return source.binary<float>(swap, what);
    case PlyType::kFloat64:
      return source.binary<double>(swap, what);
  }
  return 0.0;
}

}  // namespace

RawMesh read_ply(Source& source) {
  MeshBuilder builder(source);
  builder.set_implicit_tags(0);
  if (source.rest_of_line() != "ply") {
    source.fail("a PLY file starts with the line 'ply'");
  }
  int format = -1;  // 0 ascii, 1 binary little endian, 2 binary big endian
  std::vector<PlyElement> elements;
  for (;;) {
    const std::string_view keyword = source.token("PLY header");
    if (keyword == "end_header") {
      source.skip_line();
      break;
    }
    if (keyword == "format") {
      const std::string_view name = source.token("format");
      format = name == "ascii"                  ? 0
               : name == "binary_little_endian" ? 1
               : name == "binary_big_endian"    ? 2
                                                : -1;
      if (format < 0) {
        source.fail("unknown PLY format '" + std::string(name) + "'");
      }
      source.skip_line();
    } else if (keyword == "element") {
      PlyElement element;
      element.name = std::string(source.token("element name"));
      element.count = source.count("element count", kMaxCount);
      elements.push_back(element);
    } else if (keyword == "property") {
      if (elements.empty()) {
        source.fail("property before any element");
      }
      PlyProperty property;
      std::string_view type_name = source.token("property type");
      if (type_name == "list") {
        property.is_list = true;
        if (!ply_type(source.token("list count type"), property.count_type)) {
          source.fail("unknown list count type");
        }
        type_name = source.token("list item type");
      }
      if (!ply_type(type_name, property.type)) {
        source.fail("unknown property type '" + std::string(type_name) + "'");
      }
      property.name = std::string(source.token("property name"));
      elements.back().properties.push_back(property);
    } else if (keyword == "comment" || keyword == "obj_info") {
      source.skip_line();
    } else {
      source.fail("unknown PLY header keyword '" + std::string(keyword) + "'");
    }
  }
  if (format < 0) {
    source.fail("the PLY header has no format line");
  }
  std::vector<long long> corners;
  for (const PlyElement& element : elements) {
    const bool vertices = element.name == "vertex";
    const bool faces = element.name == "face";
    int x = -1;
    int y = -1;
    int z = -1;
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const std::string& name = element.properties[p].name;
      x = name == "x" ? static_cast<int>(p) : x;
      y = name == "y" ? static_cast<int>(p) : y;
      z = name == "z" ? static_cast<int>(p) : z;
    }
    if (vertices && (x < 0 || y < 0 || z < 0)) {
      source.fail("the vertex element lacks an x, y or z property");
    }
    for (std::size_t i = 0; i < element.count; ++i) {
      Vec3 point = Vec3::Zero();
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        if (property.is_list) {
          const double count = read_ply_value(source, format, property.count_type, "list count");
          if (count < 0 || count > 1000) {
            source.fail("list of " + std::to_string(count) + " entries is out of range");
          }
          const bool is_corners =
              faces && (property.name == "vertex_indices" || property.name == "vertex_index");
          corners.clear();
          for (int k = 0; k < static_cast<int>(count); ++k) {
            corners.push_back(static_cast<long long>(
                read_ply_value(source, format, property.type, "list entry")));
          }
          if (is_corners) {
            if (corners.size() < 3) {
              source.fail("a face needs at least 3 corners");
            }
            for (std::size_t c = 1; c + 1 < corners.size(); ++c) {
              builder.add_triangle({corners[0], corners[c], corners[c + 1]});
            }
          }
        } else {
          const double value = read_ply_value(source, format, property.type, "property");
          const auto index = static_cast<int>(p);
          if (vertices && index == x) {
            point.x() = value;
          } else if (vertices && index == y) {
            point.y() = value;
          } else if (vertices && index == z) {
            point.z() = value;
          }
        }
      }
      if (vertices) {
        builder.add_point(static_cast<long long>(i), point);
      }
    }
    if (!vertices && !faces) {
      builder.skip("PLY '" + element.name + "' elements", element.count);
    }
  }
  return builder.finish(MeshFormat::kPly);
}

}  // namespace incise::io_detail
