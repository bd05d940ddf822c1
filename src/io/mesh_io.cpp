#include "incise/io/mesh_io.hpp"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <fstream>
#include <map>
#include <pugixml.hpp>
#include <random>
#include <string_view>

#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/used_points.hpp"
#include "readers.hpp"

namespace incise {

using io_detail::Source;

std::string format_name(MeshFormat format) {
  switch (format) {
    case MeshFormat::kGmsh:
      return "Gmsh";
    case MeshFormat::kTetGen:
      return "TetGen";
    case MeshFormat::kMedit:
      return "MEDIT";
    case MeshFormat::kVtkLegacy:
      return "VTK legacy";
    case MeshFormat::kVtkXml:
      return "VTK XML";
    case MeshFormat::kObj:
      return "OBJ";
    case MeshFormat::kStl:
      return "STL";
    case MeshFormat::kPly:
      return "PLY";
    case MeshFormat::kOff:
      return "OFF";
    case MeshFormat::kUnknown:
      break;
  }
  return "unknown";
}

namespace {

MeshFormat format_from_extension(const std::filesystem::path& path) {
  const std::string extension = io_detail::lowercase(path.extension().string());
  if (extension == ".msh") {
    return MeshFormat::kGmsh;
  }
  if (extension == ".node" || extension == ".ele") {
    return MeshFormat::kTetGen;
  }
  if (extension == ".mesh") {
    return MeshFormat::kMedit;
  }
  if (extension == ".vtk") {
    return MeshFormat::kVtkLegacy;
  }
  if (extension == ".vtu" || extension == ".vtp") {
    return MeshFormat::kVtkXml;
  }
  if (extension == ".obj") {
    return MeshFormat::kObj;
  }
  if (extension == ".stl") {
    return MeshFormat::kStl;
  }
  if (extension == ".ply") {
    return MeshFormat::kPly;
  }
  if (extension == ".off") {
    return MeshFormat::kOff;
  }
  return MeshFormat::kUnknown;
}

bool starts_with(std::string_view text, std::string_view prefix) {
  return text.substr(0, prefix.size()) == prefix;
}

MeshFormat format_from_content(std::string_view bytes) {
  // Binary STL: an 80-byte header, a triangle count, 50 bytes per triangle.
  if (bytes.size() >= 84) {
    std::uint32_t count = 0;
    std::memcpy(&count, bytes.data() + 80, 4);
    if (!io_detail::kHostIsLittleEndian) {
      count = Source::byte_swapped(count);
    }
    if (84 + 50ULL * count == bytes.size()) {
      return MeshFormat::kStl;
    }
  }
  std::string_view text = bytes.substr(0, 4096);
  if (starts_with(text, "# vtk DataFile")) {
    return MeshFormat::kVtkLegacy;
  }
  // Skip blank lines and '#' comment lines to the first significant line.
  std::size_t position = 0;
  for (;;) {
    while (position < text.size() &&
           std::isspace(static_cast<unsigned char>(text[position])) != 0) {
      ++position;
    }
    if (position < text.size() && text[position] == '#') {
      position = text.find('\n', position);
      if (position == std::string_view::npos) {
        return MeshFormat::kUnknown;
      }
      continue;
    }
    break;
  }
  text = text.substr(position);
  const std::string head = io_detail::lowercase(text.substr(0, 64));
  if (starts_with(text, "$")) {
    return MeshFormat::kGmsh;
  }
  if (starts_with(text, "<?xml") || starts_with(text, "<VTKFile")) {
    return MeshFormat::kVtkXml;
  }
  if (starts_with(text, "ply\n") || starts_with(text, "ply\r\n")) {
    return MeshFormat::kPly;
  }
  const std::string_view first_word = text.substr(0, text.find_first_of(" \t\r\n"));
  for (const char* keyword : {"OFF", "COFF", "NOFF", "CNOFF", "STOFF", "STCOFF"}) {
    if (first_word == keyword) {
      return MeshFormat::kOff;
    }
  }
  if (starts_with(head, "meshversionformatted")) {
    return MeshFormat::kMedit;
  }
  if (starts_with(head, "solid") &&
      io_detail::lowercase(text.substr(0, 1024)).find("facet") != std::string::npos) {
    return MeshFormat::kStl;
  }
  for (const char* keyword : {"v ", "vn ", "vt ", "f ", "o ", "g ", "mtllib ", "usemtl ", "s "}) {
    if (starts_with(text, keyword)) {
      return MeshFormat::kObj;
    }
  }
  // TetGen: a header line of 3 or 4 integers.
  const std::string_view line = text.substr(0, text.find('\n'));
  Source header("", std::string(line));
  int integers = 0;
  long long value = 0;
  for (std::string_view token = header.next_token(); !token.empty(); token = header.next_token()) {
    if (!io_detail::parse_integer(token, value)) {
      integers = -100;
    }
    ++integers;
  }
  if (integers == 3 || integers == 4) {
    return MeshFormat::kTetGen;
  }
  return MeshFormat::kUnknown;
}

}  // namespace

MeshFormat detect_format(const std::filesystem::path& path) {
  const Source source = Source::open(path);
  const MeshFormat by_content = format_from_content(source.bytes());
  return by_content != MeshFormat::kUnknown ? by_content : format_from_extension(path);
}

RawMesh read_raw_mesh(const std::filesystem::path& path, const ReadOptions& options) {
  Source source = Source::open(path);
  MeshFormat format = format_from_content(source.bytes());
  if (format == MeshFormat::kUnknown) {
    format = format_from_extension(path);
  }
  switch (format) {
    case MeshFormat::kGmsh:
      return io_detail::read_gmsh(source);
    case MeshFormat::kTetGen: {
      // Given either file of a pair, read both (the .ele is optional).
      std::filesystem::path node_path = path;
      std::filesystem::path ele_path = path;
      node_path.replace_extension(".node");
      ele_path.replace_extension(".ele");
      Source node_source = node_path == path ? std::move(source) : Source::open(node_path);
      if (std::filesystem::exists(ele_path)) {
        Source ele_source = ele_path == path ? std::move(source) : Source::open(ele_path);
        return io_detail::read_tetgen(node_source, &ele_source);
      }
      return io_detail::read_tetgen(node_source, nullptr);
    }
    case MeshFormat::kMedit:
      return io_detail::read_medit(source);
    case MeshFormat::kVtkLegacy:
      return io_detail::read_vtk_legacy(source, options.label_array);
    case MeshFormat::kVtkXml:
      return io_detail::read_vtk_xml(source, options.label_array);
    case MeshFormat::kObj:
      return io_detail::read_obj(source);
    case MeshFormat::kStl:
      return io_detail::read_stl(source);
    case MeshFormat::kPly:
      return io_detail::read_ply(source);
    case MeshFormat::kOff:
      return io_detail::read_off(source);
    case MeshFormat::kUnknown:
      break;
  }
  throw InputError(path.string(), 0,
                   "unrecognised mesh format (supported: .msh, .node/.ele, .mesh, .vtk, .vtu, "
                   ".vtp, .obj, .stl, .ply, .off)");
}

TetMeshReadResult read_tet_mesh(const std::filesystem::path& path, const ReadOptions& options) {
  RawMesh raw = read_raw_mesh(path, options);
  if (raw.tets.empty()) {
    throw InputError(
        path.string(), 0,
        "holds no tetrahedra" + (raw.triangles.empty()
                                     ? std::string()
                                     : " (it has " + std::to_string(raw.triangles.size()) +
                                           " triangles: tetrahedralise it with `incise mesh`)"));
  }
  // Drop points no tetrahedron uses: they would carry no mass.
  std::vector<Vec3> points = raw.points;
  const std::vector<VertexId> remap = drop_unused_points(points, raw.tets);
  const std::size_t dropped = raw.points.size() - points.size();
  if (dropped > 0) {
    raw.notes.push_back("dropped " + std::to_string(dropped) + " points that no tetrahedron uses");
  }
  if (!raw.triangles.empty()) {
    raw.notes.push_back("ignored " + std::to_string(raw.triangles.size()) +
                        " triangles (the boundary is recomputed from the tetrahedra)");
  }
  if (raw.tet_labels.size() != raw.tets.size()) {
    raw.tet_labels.assign(raw.tets.size(), 0);
  }
  std::vector<Vec3> rest;
  if (raw.point_displacements.size() == raw.points.size()) {
    rest.resize(points.size());
    for (std::size_t v = 0; v < raw.points.size(); ++v) {
      if (remap[v] != kInvalidId) {
        rest[static_cast<std::size_t>(remap[v])] = raw.points[v] - raw.point_displacements[v];
      }
    }
  }
  TetMeshReadResult result{
      TetMesh(std::move(points), std::move(raw.tets), std::move(raw.tet_labels)), raw.format,
      std::move(raw.notes), dropped, std::move(rest)};
  if (raw.tet_fractions.size() == result.mesh.tet_count()) {
    std::size_t partial = 0;
    for (std::size_t t = 0; t < raw.tet_fractions.size(); ++t) {
      result.mesh.set_material_fraction(static_cast<TetId>(t), raw.tet_fractions[t]);
      partial += raw.tet_fractions[t] < 1.0 ? 1 : 0;
    }
    if (partial > 0) {
      result.notes.push_back(fmt::format(
          "{} virtual elements (XFEM: cell array 'fraction' below 1): each holds that share of "
          "its tetrahedron, and the two of a split tetrahedron overlap by design",
          partial));
    }
  }
  return result;
}

SurfaceMesh read_surface(const std::filesystem::path& path) {
  RawMesh raw = read_raw_mesh(path);
  SurfaceMesh surface;
  surface.notes = std::move(raw.notes);
  std::vector<Triangle> triangles = std::move(raw.triangles);
  if (triangles.empty() && !raw.tets.empty()) {
    const TetMesh mesh(raw.points, raw.tets);
    for (const BoundaryFace& face : boundary_faces(mesh)) {
      triangles.push_back(face.vertices);
    }
    surface.notes.push_back("used the boundary of " + std::to_string(raw.tets.size()) +
                            " tetrahedra as the surface");
  }
  if (triangles.empty()) {
    throw InputError(path.string(), 0, "holds no triangles");
  }
  std::vector<VertexId> remap(raw.points.size(), kInvalidId);
  for (Triangle& triangle : triangles) {
    for (VertexId& v : triangle) {
      if (remap[v] == kInvalidId) {
        remap[v] = static_cast<VertexId>(surface.points.size());
        surface.points.push_back(raw.points[v]);
      }
      v = remap[v];
    }
  }
  surface.triangles = std::move(triangles);
  return surface;
}

// ---- writers ------------------------------------------------------------------------------

namespace {

void check_finite_positions(const std::filesystem::path& path, std::span<const Vec3> positions) {
  for (std::size_t v = 0; v < positions.size(); ++v) {
    if (!positions[v].allFinite()) {
      throw InputError(path.string(), 0,
                       "refusing to write: vertex " + std::to_string(v) + " is NaN or infinite");
    }
  }
}

template <typename T>
void append_raw(std::string& out, const T& value) {
  const auto* bytes = reinterpret_cast<const char*>(&value);
  out.append(bytes, sizeof(T));
}

const char* host_byte_order() {
  return std::endian::native == std::endian::little ? "LittleEndian" : "BigEndian";
}

std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    std::uint32_t group = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16;
    if (i + 1 < bytes.size()) {
      group |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
    }
    if (i + 2 < bytes.size()) {
      group |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 2]));
    }
    out += kAlphabet[(group >> 18) & 63U];
    out += kAlphabet[(group >> 12) & 63U];
    out += i + 1 < bytes.size() ? kAlphabet[(group >> 6) & 63U] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[group & 63U] : '=';
  }
  return out;
}

/// VTK XML with every array inline, zlib-compressed in blocks and base64-encoded (VTK's
/// "binary" format with vtkZLibDataCompressor and UInt64 headers). Not raw appended data:
/// meshio (Debian's 5.0, and up to at least 5.3, nschloe/meshio#1324) finds appended arrays
/// by renumbering their offsets and mixes them up once an index equals another array's
/// offset; inline arrays every reader (VTK, ParaView, meshio, incise) reads alike.
class CompressedVtkXml {
 public:
  /// Adds a DataArray element holding `bytes`. An empty array is written as ascii: meshio
  /// cannot read a compressed array of no blocks.
  void add_array(const std::string& attributes, const std::string& bytes) {
    if (bytes.empty()) {
      xml += fmt::format("        <DataArray {} format=\"ascii\"></DataArray>\n", attributes);
      return;
    }
    constexpr std::size_t kBlock = 1 << 16;  // bytes of uncompressed data per block
    const std::size_t blocks = (bytes.size() + kBlock - 1) / kBlock;
    std::string header;
    append_raw(header, static_cast<std::uint64_t>(blocks));
    append_raw(header, static_cast<std::uint64_t>(kBlock));
    append_raw(header, static_cast<std::uint64_t>(bytes.size() - (blocks - 1) * kBlock));
    std::string compressed;
    for (std::size_t b = 0; b < blocks; ++b) {
      const std::size_t size = std::min(kBlock, bytes.size() - b * kBlock);
      uLongf length = compressBound(static_cast<uLong>(size));
      std::string block(length, '\0');
      const int status = compress2(reinterpret_cast<Bytef*>(block.data()), &length,
                                   reinterpret_cast<const Bytef*>(bytes.data() + b * kBlock),
                                   static_cast<uLong>(size), Z_DEFAULT_COMPRESSION);
      INCISE_ASSERT(status == Z_OK, "zlib compresses a block it has room for");
      block.resize(length);
      append_raw(header, static_cast<std::uint64_t>(length));
      compressed += block;
    }
    // The header and the data are encoded separately (as VTK writes and reads them).
    xml += fmt::format("        <DataArray {} format=\"binary\">{}{}</DataArray>\n", attributes,
                       base64(header), base64(compressed));
  }
  /// Closes the document and writes it atomically.
  void write(const std::filesystem::path& path, const char* grid) {
    xml += fmt::format("    </Piece>\n  </{}>\n</VTKFile>\n", grid);
    AtomicFile file(path);
    file.write(xml);
    file.commit();
  }

  std::string xml;  ///< the document up to the point written so far
};

std::string xyz_bytes(std::span<const Vec3> points) {
  std::string bytes;
  bytes.reserve(points.size() * 24);
  for (const Vec3& p : points) {
    append_raw(bytes, p.x());
    append_raw(bytes, p.y());
    append_raw(bytes, p.z());
  }
  return bytes;
}

}  // namespace

namespace {
bool has_labels(const TetMesh& mesh) {
  return std::any_of(mesh.tet_labels().begin(), mesh.tet_labels().end(),
                     [](int label) { return label != 0; });
}
}  // namespace

/// Appends a point or cell array (checked: its size, finite values) to a VTK XML document.
void add_field(CompressedVtkXml& document, const std::filesystem::path& path,
               const FieldArray& field, std::size_t expected_tuples) {
  std::string bytes;
  if (const auto* reals = std::get_if<std::vector<double>>(&field.values)) {
    if (reals->size() != expected_tuples * static_cast<std::size_t>(field.components)) {
      throw InputError(path.string(), 0, "field '" + field.name + "' has the wrong size");
    }
    for (std::size_t i = 0; i < reals->size(); ++i) {
      if (!std::isfinite((*reals)[i])) {
        throw InputError(path.string(), 0,
                         "refusing to write: field '" + field.name + "' value " +
                             std::to_string(i) + " is not finite");
      }
      append_raw(bytes, (*reals)[i]);
    }
    document.add_array(fmt::format("type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\"",
                                   field.name, field.components),
                       bytes);
  } else {
    const auto& integers = std::get<std::vector<std::int32_t>>(field.values);
    if (integers.size() != expected_tuples * static_cast<std::size_t>(field.components)) {
      throw InputError(path.string(), 0, "field '" + field.name + "' has the wrong size");
    }
    for (std::int32_t value : integers) {
      append_raw(bytes, value);
    }
    document.add_array(fmt::format("type=\"Int32\" Name=\"{}\" NumberOfComponents=\"{}\"",
                                   field.name, field.components),
                       bytes);
  }
}

namespace {

/// The file's field data: the time of a frame as VTK's TimeValue (what ParaView shows for a
/// single file) and the length unit as LengthUnitInMetres (numbers, which every reader takes:
/// meshio refuses VTK's String arrays), with a comment saying both in words.
void add_field_data(CompressedVtkXml& document, const VtuFields& fields) {
  if (!fields.time && !fields.length_unit_m) {
    return;
  }
  document.xml += "    <FieldData>\n";
  if (fields.length_unit_m) {
    document.xml += fmt::format("      <!-- incise: point coordinates in {}, times in s -->\n",
                                length_unit_name(fields.length_unit_m));
  }
  if (fields.time) {
    std::string bytes;
    append_raw(bytes, *fields.time);
    document.add_array("type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\"", bytes);
  }
  if (fields.length_unit_m) {
    if (!std::isfinite(*fields.length_unit_m) || *fields.length_unit_m <= 0.0) {
      throw InputError("a length unit must be a positive number of metres");
    }
    std::string bytes;
    append_raw(bytes, *fields.length_unit_m);
    document.add_array("type=\"Float64\" Name=\"LengthUnitInMetres\" NumberOfTuples=\"1\"", bytes);
  }
  document.xml += "    </FieldData>\n";
}

/// A .vtu of tetrahedra `tets` over `points`, region labels (none when empty) first.
void write_tet_vtu(const std::filesystem::path& path, std::span<const Vec3> positions,
                   std::span<const Tet> tets, std::span<const int> labels,
                   const VtuFields& fields) {
  check_finite_positions(path, positions);
  const std::size_t n_points = positions.size();
  const std::size_t n_cells = tets.size();
  for (const Tet& tet : tets) {
    for (VertexId v : tet) {
      if (v < 0 || static_cast<std::size_t>(v) >= n_points) {
        throw InputError(path.string(), 0, "a tetrahedron refers to a point that is not there");
      }
    }
  }
  // Points no tetrahedron uses (a cut's leftovers) are left out: they would stretch every
  // point array's range in ParaView and carry no material.
  const UsedPoints used_numbers = used_points(tets, n_points);
  const std::vector<VertexId>& new_index = used_numbers.index;
  if (used_numbers.count < n_points) {
    std::vector<std::size_t> kept;
    kept.reserve(used_numbers.count);
    for (std::size_t v = 0; v < n_points; ++v) {
      if (new_index[v] != kInvalidId) {
        kept.push_back(v);
      }
    }
    std::vector<Vec3> used_positions;
    used_positions.reserve(kept.size());
    for (std::size_t v : kept) {
      used_positions.push_back(positions[v]);
    }
    std::vector<Tet> renumbered(tets.begin(), tets.end());
    for (Tet& tet : renumbered) {
      for (VertexId& v : tet) {
        v = new_index[static_cast<std::size_t>(v)];
      }
    }
    VtuFields used_fields = fields;
    for (FieldArray& field : used_fields.point_data) {
      const auto width = static_cast<std::size_t>(field.components);
      std::visit(
          [&](auto& values) {
            if (values.size() != n_points * width) {
              return;  // wrong size: refused as such below
            }
            std::remove_reference_t<decltype(values)> used;
            used.reserve(kept.size() * width);
            for (std::size_t v : kept) {
              used.insert(used.end(), values.begin() + static_cast<std::ptrdiff_t>(v * width),
                          values.begin() + static_cast<std::ptrdiff_t>((v + 1) * width));
            }
            values = std::move(used);
          },
          field.values);
    }
    write_tet_vtu(path, used_positions, renumbered, labels, used_fields);
    return;
  }

  CompressedVtkXml document;
  std::string& xml = document.xml;
  const auto field_xml = [&](const FieldArray& field, std::size_t expected_tuples) {
    add_field(document, path, field, expected_tuples);
  };

  xml += fmt::format(
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
      "byte_order=\"{}\" header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n  "
      "<UnstructuredGrid>\n",
      host_byte_order());
  add_field_data(document, fields);
  xml += fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", n_points, n_cells);
  xml += "      <PointData>\n";
  for (const FieldArray& field : fields.point_data) {
    field_xml(field, n_points);
  }
  xml += "      </PointData>\n      <CellData>\n";
  // Region labels first: readers (incise, meshio) take the first integer cell array as them.
  if (!labels.empty()) {
    FieldArray region{"region", 1, std::vector<std::int32_t>(labels.begin(), labels.end())};
    field_xml(region, n_cells);
  }
  for (const FieldArray& field : fields.cell_data) {
    field_xml(field, n_cells);
  }
  xml += "      </CellData>\n      <Points>\n";
  document.add_array("type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"",
                     xyz_bytes(positions));
  xml += "      </Points>\n      <Cells>\n";
  std::string connectivity;
  std::string offsets;
  std::string types;
  connectivity.reserve(n_cells * 32);
  for (std::size_t c = 0; c < n_cells; ++c) {
    for (VertexId v : tets[c]) {
      append_raw(connectivity, static_cast<std::int64_t>(v));
    }
    append_raw(offsets, static_cast<std::int64_t>(4 * (c + 1)));
    append_raw(types, static_cast<std::uint8_t>(10));  // VTK_TETRA
  }
  document.add_array("type=\"Int64\" Name=\"connectivity\"", connectivity);
  document.add_array("type=\"Int64\" Name=\"offsets\"", offsets);
  document.add_array("type=\"UInt8\" Name=\"types\"", types);
  xml += "      </Cells>\n";
  document.write(path, "UnstructuredGrid");
}

}  // namespace

void write_vtu(const std::filesystem::path& path, const TetMesh& mesh,
               std::span<const Vec3> positions, const VtuFields& fields) {
  if (positions.empty()) {
    positions = mesh.rest_positions();
  }
  if (positions.size() != mesh.vertex_count()) {
    throw InputError(path.string(), 0, "position count does not match the mesh");
  }
  write_tet_vtu(path, positions, mesh.tets(),
                has_labels(mesh) ? mesh.tet_labels() : std::span<const int>(), fields);
}

void write_vtu(const std::filesystem::path& path, std::span<const Vec3> points,
               std::span<const Tet> tets, const VtuFields& fields) {
  write_tet_vtu(path, points, tets, {}, fields);
}

void write_vtp(const std::filesystem::path& path, std::span<const Vec3> points,
               std::span<const Triangle> triangles, const VtuFields& fields) {
  check_finite_positions(path, points);
  CompressedVtkXml document;
  document.xml = fmt::format(
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"{}\" "
      "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n  <PolyData>\n",
      host_byte_order());
  add_field_data(document, fields);
  document.xml +=
      fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfPolys=\"{}\">\n      <PointData>\n",
                  points.size(), triangles.size());
  for (const FieldArray& field : fields.point_data) {
    add_field(document, path, field, points.size());
  }
  document.xml += "      </PointData>\n      <CellData>\n";
  for (const FieldArray& field : fields.cell_data) {
    add_field(document, path, field, triangles.size());
  }
  document.xml += "      </CellData>\n      <Points>\n";
  document.add_array("type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"",
                     xyz_bytes(points));
  document.xml += "      </Points>\n      <Polys>\n";
  std::string connectivity;
  std::string offsets;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (VertexId v : triangles[t]) {
      append_raw(connectivity, static_cast<std::int64_t>(v));
    }
    append_raw(offsets, static_cast<std::int64_t>(3 * (t + 1)));
  }
  document.add_array("type=\"Int64\" Name=\"connectivity\"", connectivity);
  document.add_array("type=\"Int64\" Name=\"offsets\"", offsets);
  document.xml += "      </Polys>\n";
  document.write(path, "PolyData");
}

PvdSeries::PvdSeries(std::filesystem::path pvd_path) : path_(std::move(pvd_path)) {}

void PvdSeries::keep_existing_before(double time) {
  entries_.clear();
  pugi::xml_document document;
  if (!std::filesystem::exists(path_) || !document.load_file(path_.c_str())) {
    return;  // nothing to continue: the series starts afresh
  }
  for (const pugi::xml_node entry :
       document.child("VTKFile").child("Collection").children("DataSet")) {
    const double entry_time = entry.attribute("timestep").as_double();
    if (entry_time < time) {
      entries_.emplace_back(entry_time, entry.attribute("file").as_string());
    }
  }
}

void PvdSeries::add(double time, const std::string& file) {
  entries_.emplace_back(time, file);
  std::string xml = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n";
  if (length_unit_m_) {
    xml += fmt::format("  <!-- incise: point coordinates in {}, timesteps in s -->\n",
                       length_unit_name(length_unit_m_));
  }
  xml += "  <Collection>\n";
  for (const auto& [entry_time, entry_file] : entries_) {
    // 12 significant digits: a time summed from frame steps shows as 0.35, not as
    // 0.35000000000000003.
    xml += fmt::format("    <DataSet timestep=\"{:.12g}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
                       entry_time, entry_file);
  }
  xml += "  </Collection>\n</VTKFile>\n";
  AtomicFile out(path_);
  out.write(xml);
  out.commit();
}

namespace {
/// Gmsh physical group (dimension 2) of a cut's faces, named "cut".
constexpr int kCutGroup = 1;
}  // namespace

void write_msh(const std::filesystem::path& path, const TetMesh& mesh) {
  check_finite_positions(path, mesh.rest_positions());
  const std::size_t m = mesh.tet_count();
  const auto [low, high] = bounding_box(mesh);
  // One volume entity per region label, with the label as its physical group (Gmsh has no
  // physical group 0: those tetrahedra get an entity without one).
  std::map<int, std::vector<std::size_t>> regions;
  for (std::size_t t = 0; t < m; ++t) {
    regions[mesh.tet_label(static_cast<TetId>(t))].push_back(t);
  }
  if (regions.empty()) {
    regions[0];
  }
  // A cut's faces (its lips, back to back on duplicated nodes) as triangles of a surface
  // entity in the physical group "cut": a Gmsh user can tell the wound from the skin, and
  // sees what Coherence (which merges the duplicated nodes) would close.
  const std::vector<BoundaryFace> faces = boundary_faces(mesh);
  const std::vector<bool> lips = lip_faces(mesh, faces);
  const auto cut_faces = static_cast<std::size_t>(std::count(lips.begin(), lips.end(), true));
  std::string out = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
  if (cut_faces > 0) {
    out += fmt::format("$PhysicalNames\n1\n2 {} \"cut\"\n$EndPhysicalNames\n", kCutGroup);
  }
  out += fmt::format("$Entities\n0 0 {} {}\n", cut_faces > 0 ? 1 : 0, regions.size());
  if (cut_faces > 0) {
    out += fmt::format("1 {} {} {} {} {} {} 1 {} 0\n", low.x(), low.y(), low.z(), high.x(),
                       high.y(), high.z(), kCutGroup);
  }
  int entity = 0;
  for (const auto& [label, tets] : regions) {
    out += fmt::format("{} {} {} {} {} {} {} ", ++entity, low.x(), low.y(), low.z(), high.x(),
                       high.y(), high.z());
    out += label != 0 ? fmt::format("1 {} 0\n", label) : std::string("0 0\n");
  }
  out += "$EndEntities\n";
  const UsedPoints used = used_points(mesh.tets(), mesh.vertex_count());
  const std::size_t n = used.count;
  const auto node = [&used](VertexId v) { return used.index[static_cast<std::size_t>(v)] + 1; };
  out += fmt::format("$Nodes\n1 {} 1 {}\n3 1 0 {}\n", n, n, n);
  for (std::size_t v = 1; v <= n; ++v) {
    out += fmt::format("{}\n", v);
  }
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (used.index[v] != kInvalidId) {
      const Vec3& p = mesh.rest_position(static_cast<VertexId>(v));
      out += fmt::format("{} {} {}\n", p.x(), p.y(), p.z());
    }
  }
  const std::size_t elements = m + cut_faces;
  out += fmt::format("$EndNodes\n$Elements\n{} {} 1 {}\n", regions.size() + (cut_faces > 0 ? 1 : 0),
                     elements, elements);
  entity = 0;
  std::size_t tag = 0;
  for (const auto& [label, tets] : regions) {
    out += fmt::format("3 {} 4 {}\n", ++entity, tets.size());
    for (std::size_t t : tets) {
      const Tet& tet = mesh.tet(static_cast<TetId>(t));
      out += fmt::format("{} {} {} {} {}\n", ++tag, node(tet[0]), node(tet[1]), node(tet[2]),
                         node(tet[3]));
    }
  }
  if (cut_faces > 0) {
    out += fmt::format("2 1 2 {}\n", cut_faces);
    for (std::size_t f = 0; f < faces.size(); ++f) {
      if (lips[f]) {
        const Triangle& v = faces[f].vertices;
        out += fmt::format("{} {} {} {}\n", ++tag, node(v[0]), node(v[1]), node(v[2]));
      }
    }
  }
  out += "$EndElements\n";
  AtomicFile file(path);
  file.write(out);
  file.commit();
}

void write_medit(const std::filesystem::path& path, const TetMesh& mesh) {
  check_finite_positions(path, mesh.rest_positions());
  const UsedPoints used = used_points(mesh.tets(), mesh.vertex_count());
  const auto node = [&used](VertexId v) { return used.index[static_cast<std::size_t>(v)] + 1; };
  std::string out = fmt::format("MeshVersionFormatted 2\nDimension 3\nVertices\n{}\n", used.count);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (used.index[v] != kInvalidId) {
      const Vec3& p = mesh.rest_position(static_cast<VertexId>(v));
      out += fmt::format("{} {} {} 0\n", p.x(), p.y(), p.z());
    }
  }
  out += fmt::format("Tetrahedra\n{}\n", mesh.tet_count());
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    out += fmt::format("{} {} {} {} {}\n", node(tet[0]), node(tet[1]), node(tet[2]), node(tet[3]),
                       mesh.tet_label(static_cast<TetId>(t)));
  }
  // The boundary triangles, a cut's faces (its lips) with reference 1, the rest 0.
  const auto faces = boundary_faces(mesh);
  const std::vector<bool> lips = lip_faces(mesh, faces);
  out += fmt::format("Triangles\n{}\n", faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const Triangle& v = faces[f].vertices;
    out += fmt::format("{} {} {} {}\n", node(v[0]), node(v[1]), node(v[2]), lips[f] ? 1 : 0);
  }
  out += "End\n";
  AtomicFile file(path);
  file.write(out);
  file.commit();
}

void write_obj(const std::filesystem::path& path, std::span<const Vec3> points,
               std::span<const Triangle> triangles) {
  check_finite_positions(path, points);
  std::string out = "# written by incise\n";
  for (const Vec3& p : points) {
    out += fmt::format("v {} {} {}\n", p.x(), p.y(), p.z());
  }
  for (const Triangle& t : triangles) {
    out += fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  }
  AtomicFile file(path);
  file.write(out);
  file.commit();
}

void write_obj(const std::filesystem::path& path, const TetMesh& mesh) {
  std::vector<VertexId> remap(mesh.vertex_count(), kInvalidId);
  std::vector<Vec3> points;
  std::vector<Triangle> triangles;
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    Triangle triangle = face.vertices;
    for (VertexId& v : triangle) {
      if (remap[v] == kInvalidId) {
        remap[v] = static_cast<VertexId>(points.size());
        points.push_back(mesh.rest_position(v));
      }
      v = remap[v];
    }
    triangles.push_back(triangle);
  }
  write_obj(path, points, triangles);
}

void write_tetgen(const std::filesystem::path& path, const TetMesh& mesh) {
  check_finite_positions(path, mesh.rest_positions());
  std::filesystem::path node_path = path;
  std::filesystem::path ele_path = path;
  node_path.replace_extension(".node");
  ele_path.replace_extension(".ele");
  std::string node = fmt::format("{} 3 0 0\n", mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3& p = mesh.rest_position(static_cast<VertexId>(v));
    node += fmt::format("{} {} {} {}\n", v, p.x(), p.y(), p.z());
  }
  // Region labels as TetGen's region attribute, when there are any.
  const bool labelled = has_labels(mesh);
  std::string ele = fmt::format("{} 4 {}\n", mesh.tet_count(), labelled ? 1 : 0);
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    ele += fmt::format("{} {} {} {} {}", t, tet[0], tet[1], tet[2], tet[3]);
    ele += labelled ? fmt::format(" {}\n", mesh.tet_label(static_cast<TetId>(t))) : "\n";
  }
  AtomicFile node_file(node_path);
  node_file.write(node);
  AtomicFile ele_file(ele_path);
  ele_file.write(ele);
  node_file.commit();
  ele_file.commit();
}

void write_tet_mesh(const std::filesystem::path& path, const TetMesh& mesh,
                    std::optional<double> length_unit_m) {
  const std::string extension = io_detail::lowercase(path.extension().string());
  if (extension == ".msh") {
    write_msh(path, mesh);
  } else if (extension == ".vtu") {
    VtuFields fields;
    fields.length_unit_m = length_unit_m;
    write_vtu(path, mesh, {}, fields);
  } else if (extension == ".mesh") {
    write_medit(path, mesh);
  } else if (extension == ".obj") {
    write_obj(path, mesh);
  } else if (extension == ".node" || extension == ".ele") {
    write_tetgen(path, mesh);
  } else {
    throw InputError(path.string(), 0,
                     "cannot write this extension (use .msh, .vtu, .mesh, .obj or .node)");
  }
}

std::string length_unit_name(std::optional<double> length_unit_m) {
  if (!length_unit_m) {
    return "mesh units";
  }
  for (const auto& [metres, name] :
       {std::pair{1.0, "m"}, std::pair{1e-2, "cm"}, std::pair{1e-3, "mm"}, std::pair{1e-6, "um"}}) {
    if (std::abs(*length_unit_m - metres) <= 1e-12 * metres) {
      return name;
    }
  }
  return fmt::format("units of {:.12g} m", *length_unit_m);
}

}  // namespace incise
