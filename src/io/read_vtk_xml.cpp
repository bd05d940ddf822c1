// VTK XML reader (.vtu UnstructuredGrid, .vtp PolyData): ascii, inline base64, appended raw or
// base64 data, optionally zlib-compressed, either byte order, UInt32 or UInt64 headers.
// pugixml parses the XML; zlib inflates. The binary layout handling is ours because neither
// library knows VTK's block headers.

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <pugixml.hpp>

#include "readers.hpp"

namespace incise::io_detail {
namespace {

std::size_t type_size(std::string_view type) {
  if (type == "Int8" || type == "UInt8") {
    return 1;
  }
  if (type == "Int16" || type == "UInt16") {
    return 2;
  }
  if (type == "Int32" || type == "UInt32" || type == "Float32") {
    return 4;
  }
  if (type == "Int64" || type == "UInt64" || type == "Float64") {
    return 8;
  }
  return 0;
}

int base64_value(char c) {
  if (c >= 'A' && c <= 'Z') {
    return c - 'A';
  }
  if (c >= 'a' && c <= 'z') {
    return c - 'a' + 26;
  }
  if (c >= '0' && c <= '9') {
    return c - '0' + 52;
  }
  if (c == '+') {
    return 62;
  }
  if (c == '/') {
    return 63;
  }
  return -1;
}

std::size_t base64_chars(std::size_t bytes) {
  return 4 * ((bytes + 2) / 3);
}

class VtkXmlReader {
 public:
  VtkXmlReader(Source& source, std::string label_array)
      : source_(source), builder_(source), label_array_(std::move(label_array)) {
    source_.disable_line_numbers();  // the cursor does not walk the XML: name elements instead
  }

  RawMesh read() {
    const std::string_view bytes = source_.bytes();
    // Appended raw data is not XML: cut it out and parse the rest.
    std::string xml(bytes);
    const std::size_t appended_tag = bytes.find("<AppendedData");
    if (appended_tag != std::string_view::npos) {
      const std::size_t tag_end = bytes.find('>', appended_tag);
      const std::size_t marker =
          tag_end == std::string_view::npos ? tag_end : bytes.find('_', tag_end);
      if (marker == std::string_view::npos) {
        fail_at(appended_tag, "AppendedData without the '_' that starts the data");
      }
      appended_ = bytes.substr(marker + 1);
      const std::size_t close = appended_.rfind("</AppendedData>");
      if (close != std::string_view::npos) {
        appended_ = appended_.substr(0, close);
      }
      xml = std::string(bytes.substr(0, marker)) + "</AppendedData></VTKFile>";
    }
    const pugi::xml_parse_result parsed =
        document_.load_buffer(xml.data(), xml.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!parsed) {
      fail_at(static_cast<std::size_t>(parsed.offset),
              std::string("malformed XML: ") + parsed.description());
    }
    const pugi::xml_node root = document_.child("VTKFile");
    if (!root) {
      fail_at(0, "no <VTKFile> element");
    }
    const std::string type = root.attribute("type").as_string();
    if (type != "UnstructuredGrid" && type != "PolyData") {
      fail_at(root, "VTKFile type '" + type + "' holds no tetrahedra or triangles");
    }
    swap_ = (std::string(root.attribute("byte_order").as_string("LittleEndian")) == "BigEndian") ==
            kHostIsLittleEndian;
    const std::string header_type = root.attribute("header_type").as_string("UInt32");
    if (header_type != "UInt32" && header_type != "UInt64") {
      fail_at(root, "unsupported header_type '" + header_type + "'");
    }
    header_bytes_ = header_type == "UInt64" ? 8 : 4;
    const std::string compressor = root.attribute("compressor").as_string("");
    if (!compressor.empty() && compressor != "vtkZLibDataCompressor") {
      fail_at(root, "unsupported compressor '" + compressor + "' (only zlib is)");
    }
    compressed_ = !compressor.empty();
    const pugi::xml_node appended = root.child("AppendedData");
    appended_base64_ =
        appended && std::string(appended.attribute("encoding").as_string("raw")) == "base64";

    const pugi::xml_node grid = root.child(type.c_str());
    if (!grid) {
      fail_at(root, "no <" + type + "> element");
    }
    builder_.set_implicit_tags(0);
    std::size_t pieces = 0;
    for (const pugi::xml_node piece : grid.children("Piece")) {
      read_piece(piece, type == "PolyData");
      ++pieces;
    }
    if (pieces == 0) {
      fail_at(grid, "no <Piece> element");
    }
    RawMesh raw = builder_.finish(MeshFormat::kVtkXml);
    if (any_fraction_) {
      raw.tet_fractions = std::move(fractions_);
    }
    if (any_displacement_) {
      displacements_.resize(raw.points.size(), Vec3::Zero());
      raw.point_displacements = std::move(displacements_);
    }
    return raw;
  }

 private:
  [[noreturn]] void fail_at(std::size_t offset, const std::string& message) const {
    const std::string_view bytes = source_.bytes();
    const auto line =
        1 + static_cast<std::size_t>(std::count(
                bytes.begin(),
                bytes.begin() + static_cast<std::ptrdiff_t>(std::min(offset, bytes.size())), '\n'));
    throw InputError(source_.name(), line, message);
  }
  [[noreturn]] void fail_at(const pugi::xml_node& node, const std::string& message) const {
    fail_at(static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, node.offset_debug())), message);
  }

  std::size_t count_attribute(const pugi::xml_node& node, const char* name) const {
    const pugi::xml_attribute attribute = node.attribute(name);
    long long value = -1;
    if (!attribute || !parse_integer(attribute.value(), value) || value < 0 ||
        static_cast<std::size_t>(value) > kMaxCount) {
      fail_at(node, std::string("missing or bad ") + name);
    }
    return static_cast<std::size_t>(value);
  }

  static pugi::xml_node named_array(const pugi::xml_node& parent, const char* name) {
    for (const pugi::xml_node array : parent.children("DataArray")) {
      if (std::string(array.attribute("Name").as_string()) == name) {
        return array;
      }
    }
    return {};
  }

  void read_piece(const pugi::xml_node& piece, bool polydata) {
    const std::size_t point_count = count_attribute(piece, "NumberOfPoints");
    const auto first_point = static_cast<long long>(builder_.point_count());
    const pugi::xml_node points = piece.child("Points").child("DataArray");
    if (!points) {
      fail_at(piece, "a Piece without Points/DataArray");
    }
    const std::vector<double> xyz = values(points, 3 * point_count, "Points");
    for (std::size_t i = 0; i < point_count; ++i) {
      builder_.add_point(first_point + static_cast<long long>(i),
                         Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]));
    }
    // A frame's points are deformed; its "displacement" from the rest shape (as incise and
    // most FE post-processors write it) gives the rest shape back.
    const pugi::xml_node moved = named_array(piece.child("PointData"), "displacement");
    if (moved && moved.attribute("NumberOfComponents").as_int(1) == 3) {
      const std::vector<double> d = values(moved, 3 * point_count, "displacement");
      displacements_.resize(static_cast<std::size_t>(first_point), Vec3::Zero());
      for (std::size_t i = 0; i < point_count; ++i) {
        displacements_.emplace_back(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
      }
      any_displacement_ = true;
    }
    if (polydata) {
      for (const char* section : {"Polys", "Strips"}) {
        const std::size_t count = count_attribute_or_zero(piece, std::string("NumberOf") + section);
        if (count == 0) {
          continue;
        }
        const pugi::xml_node block = piece.child(section);
        const auto [connectivity, offsets] = cell_arrays(block, count, section);
        for (std::size_t c = 0; c < count; ++c) {
          const std::size_t begin = c == 0 ? 0 : static_cast<std::size_t>(offsets[c - 1]);
          const std::size_t size = static_cast<std::size_t>(offsets[c]) - begin;
          if (size < 3) {
            fail_at(block, std::string(section) + " cell " + std::to_string(c) +
                               " has fewer than 3 points");
          }
          for (std::size_t i = 0; i + 2 < size; ++i) {
            const long long a = first_point + static_cast<long long>(connectivity[begin]);
            const long long b = first_point + static_cast<long long>(connectivity[begin + i + 1]);
            const long long d = first_point + static_cast<long long>(connectivity[begin + i + 2]);
            if (std::string(section) == "Polys") {
              builder_.add_triangle({a, b, d});
            } else {
              const long long s0 = first_point + static_cast<long long>(connectivity[begin + i]);
              builder_.add_triangle(i % 2 == 0 ? std::array{s0, b, d} : std::array{b, s0, d});
            }
          }
        }
      }
      for (const char* section : {"Verts", "Lines"}) {
        const std::size_t count = count_attribute_or_zero(piece, std::string("NumberOf") + section);
        if (count > 0) {
          builder_.skip(std::string(section) == "Verts" ? "vertex cells" : "line cells", count);
        }
      }
      return;
    }
    const std::size_t cell_count = count_attribute(piece, "NumberOfCells");
    const pugi::xml_node cells = piece.child("Cells");
    if (!cells) {
      fail_at(piece, "a Piece without Cells");
    }
    // A named pair, not a structured binding: clang 14 cannot capture those in lambdas.
    const auto cell_data = cell_arrays(cells, cell_count, "Cells");
    const std::vector<double>& connectivity = cell_data.first;
    const std::vector<double>& offsets = cell_data.second;
    const pugi::xml_node types_node = named_array(cells, "types");
    if (!types_node) {
      fail_at(cells, "Cells without a 'types' DataArray");
    }
    const std::vector<double> types = values(types_node, cell_count, "types");
    const std::vector<double> labels = region_labels(piece, cell_count);
    const std::vector<double> fractions = material_fractions(piece, cell_count);
    for (std::size_t c = 0; c < cell_count; ++c) {
      const std::size_t begin = c == 0 ? 0 : static_cast<std::size_t>(offsets[c - 1]);
      const std::size_t size = static_cast<std::size_t>(offsets[c]) - begin;
      if (types[c] < 0.0 || types[c] > 255.0 || types[c] != std::floor(types[c])) {
        fail_at(types_node, "cell " + std::to_string(c) + " has no VTK cell type (" +
                                fmt::format("{}", types[c]) + ")");
      }
      const auto type = static_cast<int>(types[c]);
      auto id = [&](std::size_t k) {
        return first_point + static_cast<long long>(connectivity[begin + k]);
      };
      if ((type == 10 && size == 4) || (type == 24 && size == 10)) {
        builder_.add_tet({id(0), id(1), id(2), id(3)},
                         labels.empty() ? 0 : static_cast<long long>(labels[c]));
        fractions_.push_back(fractions.empty() ? 1.0 : fractions[c]);
        if (type == 24) {
          builder_.skip("mid-edge nodes (kept the corners of quadratic tetrahedra)", 6);
        }
      } else if ((type == 5 && size == 3) || (type == 22 && size == 6)) {
        builder_.add_triangle({id(0), id(1), id(2)});
      } else if (type == 10 || type == 5) {
        fail_at(cells, "cell " + std::to_string(c) + " of type " + std::to_string(type) + " has " +
                           std::to_string(size) + " points");
      } else {
        builder_.skip(vtk_cell_name(type));
      }
    }
  }

  /// XFEM material fractions per cell (the one-component cell array "fraction" incise writes
  /// for virtual elements), or none; each must lie in (0, 1].
  std::vector<double> material_fractions(const pugi::xml_node& piece, std::size_t cell_count) {
    for (const pugi::xml_node array : piece.child("CellData").children("DataArray")) {
      if (std::string(array.attribute("Name").as_string()) != "fraction" ||
          array.attribute("NumberOfComponents").as_int(1) != 1) {
        continue;
      }
      std::vector<double> fractions = values(array, cell_count, "material fractions");
      for (std::size_t c = 0; c < fractions.size(); ++c) {
        if (!(fractions[c] > 0.0 && fractions[c] <= 1.0)) {
          fail_at(array, "cell " + std::to_string(c) + ": material fraction " +
                             fmt::format("{}", fractions[c]) + " is not in (0, 1]");
        }
      }
      any_fraction_ = true;
      return fractions;
    }
    return {};
  }

  /// Region labels per cell: the CellData array named by the caller, else the first
  /// one-component integer one (a "subdomain index", "region" or "gmsh:physical" array), or
  /// none.
  std::vector<double> region_labels(const pugi::xml_node& piece, std::size_t cell_count) {
    std::string names;
    for (const pugi::xml_node array : piece.child("CellData").children("DataArray")) {
      const std::string name = array.attribute("Name").as_string();
      names += (names.empty() ? "" : ", ") + name;
      const std::string type = array.attribute("type").as_string();
      const bool integer = type.rfind("Int", 0) == 0 || type.rfind("UInt", 0) == 0;
      const bool named = !label_array_.empty() && name == label_array_;
      if ((!label_array_.empty() && !named) || (!named && !integer) ||
          array.attribute("NumberOfComponents").as_int(1) != 1) {
        if (named) {
          fail_at(array, "cell array '" + name + "' has several components: not region labels");
        }
        continue;
      }
      std::vector<double> labels = values(array, cell_count, "region labels");
      for (double label : labels) {
        if (std::abs(label) > 2e9 || label != std::floor(label)) {
          fail_at(array, "region label " + std::to_string(label) + " is not a whole number");
        }
      }
      return labels;
    }
    if (!label_array_.empty()) {
      fail_at(piece, "no cell array named '" + label_array_ + "' for region labels (cell arrays: " +
                         (names.empty() ? std::string("none") : names) + ")");
    }
    return {};
  }

  std::size_t count_attribute_or_zero(const pugi::xml_node& node, const std::string& name) const {
    return node.attribute(name.c_str()) ? count_attribute(node, name.c_str()) : 0;
  }

  /// connectivity and offsets of a Cells/Polys block, checked for consistency.
  std::pair<std::vector<double>, std::vector<double>> cell_arrays(const pugi::xml_node& block,
                                                                  std::size_t count,
                                                                  const char* section) {
    const pugi::xml_node connectivity_node = named_array(block, "connectivity");
    const pugi::xml_node offsets_node = named_array(block, "offsets");
    if (!connectivity_node || !offsets_node) {
      fail_at(block, std::string(section) + " needs 'connectivity' and 'offsets' DataArrays");
    }
    std::vector<double> offsets = values(offsets_node, count, "offsets");
    double previous = 0.0;
    for (std::size_t c = 0; c < count; ++c) {
      if (offsets[c] < previous) {
        fail_at(offsets_node, "offsets decrease at cell " + std::to_string(c));
      }
      previous = offsets[c];
    }
    if (previous > static_cast<double>(kMaxCount)) {
      fail_at(offsets_node, "the last offset " + fmt::format("{}", previous) + " is out of range");
    }
    const auto connectivity_size = static_cast<std::size_t>(previous);
    std::vector<double> connectivity = values(connectivity_node, connectivity_size, "connectivity");
    for (std::size_t i = 0; i < connectivity.size(); ++i) {
      // Point ids become integers below; a float array may hold anything.
      if (connectivity[i] < 0.0 || connectivity[i] > static_cast<double>(kMaxCount) ||
          connectivity[i] != std::floor(connectivity[i])) {
        fail_at(connectivity_node, "connectivity value " + std::to_string(i) + " (" +
                                       fmt::format("{}", connectivity[i]) + ") is not a point id");
      }
    }
    return {std::move(connectivity), std::move(offsets)};
  }

  /// Decoded bytes of a base64 stream; fails on a character outside the alphabet.
  std::string decode_base64(std::string_view text, const pugi::xml_node& node) const {
    std::string out;
    out.reserve(text.size() / 4 * 3);
    std::uint32_t accumulator = 0;
    int bits = 0;
    for (char c : text) {
      if (c == '=') {
        break;
      }
      const int value = base64_value(c);
      if (value < 0) {
        fail_at(node, std::string("invalid base64 character '") + c + "'");
      }
      accumulator = (accumulator << 6U) | static_cast<std::uint32_t>(value);
      bits += 6;
      if (bits >= 8) {
        bits -= 8;
        out.push_back(static_cast<char>((accumulator >> static_cast<unsigned>(bits)) & 0xffU));
      }
    }
    return out;
  }

  std::uint64_t header_value(std::string_view bytes, std::size_t index,
                             const pugi::xml_node& node) const {
    if (bytes.size() < (index + 1) * header_bytes_) {
      fail_at(node, "binary data shorter than its header");
    }
    if (header_bytes_ == 8) {
      std::uint64_t value = 0;
      std::memcpy(&value, bytes.data() + index * 8, 8);
      return swap_ ? Source::byte_swapped(value) : value;
    }
    std::uint32_t value = 0;
    std::memcpy(&value, bytes.data() + index * 4, 4);
    return swap_ ? Source::byte_swapped(value) : value;
  }

  /// Inflates zlib blocks described by `header` from `data`.
  std::string inflate_blocks(std::string_view header, std::string_view data,
                             const pugi::xml_node& node) const {
    const std::uint64_t blocks = header_value(header, 0, node);
    const std::uint64_t block_size = header_value(header, 1, node);
    const std::uint64_t last_size = header_value(header, 2, node);
    if (blocks > kMaxCount || block_size > (1ULL << 32U)) {
      fail_at(node, "bad compression header");
    }
    std::string out;
    std::size_t position = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      const std::uint64_t compressed = header_value(header, 3 + b, node);
      const std::uint64_t expected = (b + 1 == blocks && last_size != 0) ? last_size : block_size;
      if (position + compressed > data.size()) {
        fail_at(node, "compressed data shorter than its header says");
      }
      // zlib cannot inflate beyond about 1032:1, so a header claiming more is refused before
      // anything is allocated for it (a 1 KB file must not make us allocate 2 GB).
      if (expected > 1032 * compressed + 64) {
        fail_at(node, "zlib block " + std::to_string(b) + " claims " + std::to_string(expected) +
                          " bytes from " + std::to_string(compressed) + " compressed bytes");
      }
      std::string block(expected, '\0');
      uLongf produced = static_cast<uLongf>(expected);
      const int status = uncompress(reinterpret_cast<Bytef*>(block.data()), &produced,
                                    reinterpret_cast<const Bytef*>(data.data() + position),
                                    static_cast<uLong>(compressed));
      if (status != Z_OK || produced != expected) {
        fail_at(node, "zlib block " + std::to_string(b) + " does not inflate");
      }
      out += block;
      position += compressed;
    }
    return out;
  }

  /// The raw value bytes of one binary DataArray, from raw or base64 text.
  std::string binary_payload(std::string_view text, bool is_base64,
                             const pugi::xml_node& node) const {
    if (!is_base64) {
      const std::uint64_t first = header_value(text, 0, node);
      if (!compressed_) {
        if (header_bytes_ + first > text.size()) {
          fail_at(node, "appended data shorter than its header says");
        }
        return std::string(text.substr(header_bytes_, first));
      }
      const std::size_t header_size = (3 + first) * header_bytes_;
      if (first > kMaxCount || header_size > text.size()) {
        fail_at(node, "bad compression header");
      }
      return inflate_blocks(text.substr(0, header_size), text.substr(header_size), node);
    }
    // Base64: the header is either encoded on its own (VTK) or together with the data.
    std::string compact;
    compact.reserve(text.size());
    for (char c : text) {
      if (std::isspace(static_cast<unsigned char>(c)) == 0) {
        compact.push_back(c);
      }
    }
    const std::string lead =
        decode_base64(std::string_view(compact).substr(0, base64_chars(header_bytes_)), node);
    const std::uint64_t first = header_value(lead, 0, node);
    if (first > (1ULL << 40U)) {
      fail_at(node, "bad binary header");
    }
    const std::size_t header_size = compressed_ ? (3 + first) * header_bytes_ : header_bytes_;
    const std::size_t header_chars = base64_chars(header_size);
    const bool separate = header_size % 3 == 0 ||
                          (compact.size() >= header_chars && compact[header_chars - 1] == '=');
    std::string header;
    std::string rest;
    if (separate) {
      header = decode_base64(std::string_view(compact).substr(0, header_chars), node);
      rest = decode_base64(std::string_view(compact).substr(std::min(header_chars, compact.size())),
                           node);
    } else {
      const std::string all = decode_base64(compact, node);
      header = all.substr(0, std::min(header_size, all.size()));
      rest = all.size() > header_size ? all.substr(header_size) : std::string();
    }
    if (header.size() < header_size) {
      fail_at(node, "binary data shorter than its header");
    }
    if (!compressed_) {
      if (rest.size() < first) {
        fail_at(node, "binary data shorter than its header says");
      }
      rest.resize(first);
      return rest;
    }
    return inflate_blocks(header, rest, node);
  }

  /// Exactly `count` values of a DataArray as doubles.
  std::vector<double> values(const pugi::xml_node& node, std::size_t count,
                             const char* what) const {
    const std::string type = node.attribute("type").as_string();
    const std::size_t size = type_size(type);
    if (size == 0) {
      fail_at(node, std::string(what) + ": unknown DataArray type '" + type + "'");
    }
    const std::string format = node.attribute("format").as_string("ascii");
    std::vector<double> out;
    if (format == "ascii") {
      Source text(source_.name(), node.text().as_string());
      if (!Source::text_can_hold(count, text.remaining())) {
        fail_at(node, std::string(what) + ": " + std::to_string(count) +
                          " values needed, but the array's text holds at most " +
                          std::to_string((text.remaining() + 1) / 2));
      }
      out.reserve(count);
      const bool integral = type.find("Int") != std::string::npos;
      for (std::size_t i = 0; i < count; ++i) {
        const std::string_view token = text.next_token();
        double value = 0.0;
        long long integer = 0;
        bool parsed = false;
        if (integral) {
          parsed = parse_integer(token, integer);
          value = static_cast<double>(integer);
        } else {
          parsed = parse_real(token, value) && std::isfinite(value);
        }
        if (!parsed) {
          fail_at(node, std::string(what) + ": value " + std::to_string(i) + " of " +
                            std::to_string(count) + " is missing or not a number ('" +
                            std::string(token) + "')");
        }
        out.push_back(value);
      }
      return out;
    }
    std::string payload;
    if (format == "binary") {
      payload = binary_payload(node.text().as_string(), true, node);
    } else if (format == "appended") {
      long long offset = -1;
      if (!parse_integer(node.attribute("offset").as_string(), offset) || offset < 0 ||
          static_cast<std::size_t>(offset) >= appended_.size()) {
        fail_at(node, std::string(what) + ": missing or bad appended offset");
      }
      payload = binary_payload(appended_.substr(static_cast<std::size_t>(offset)), appended_base64_,
                               node);
    } else {
      fail_at(node, std::string(what) + ": unknown DataArray format '" + format + "'");
    }
    if (payload.size() < count * size) {
      fail_at(node, std::string(what) + ": " + std::to_string(payload.size() / size) +
                        " values where " + std::to_string(count) + " are needed");
    }
    out.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
      const char* p = payload.data() + i * size;
      double value = 0.0;
      auto load = [&](auto sample) {
        std::memcpy(&sample, p, sizeof(sample));
        value = static_cast<double>(swap_ ? Source::byte_swapped(sample) : sample);
      };
      if (type == "Float32") {
        load(float{});
      } else if (type == "Float64") {
        load(double{});
      } else if (type == "Int8") {
        load(std::int8_t{});
      } else if (type == "UInt8") {
        load(std::uint8_t{});
      } else if (type == "Int16") {
        load(std::int16_t{});
      } else if (type == "UInt16") {
        load(std::uint16_t{});
      } else if (type == "Int32") {
        load(std::int32_t{});
      } else if (type == "UInt32") {
        load(std::uint32_t{});
      } else if (type == "Int64") {
        load(std::int64_t{});
      } else {
        load(std::uint64_t{});
      }
      if (!std::isfinite(value)) {
        fail_at(node, std::string(what) + ": value " + std::to_string(i) + " is not finite");
      }
      out.push_back(value);
    }
    return out;
  }

  Source& source_;
  MeshBuilder builder_;
  pugi::xml_document document_;
  std::string_view appended_;
  bool appended_base64_ = false;
  bool swap_ = false;
  bool compressed_ = false;
  std::size_t header_bytes_ = 4;
  std::string label_array_;
  std::vector<double> fractions_;  ///< per tetrahedron read (1 where the file has none)
  bool any_fraction_ = false;
  std::vector<Vec3> displacements_;  ///< per point read (0 in pieces without the array)
  bool any_displacement_ = false;
};

}  // namespace

RawMesh read_vtk_xml(Source& source, const std::string& label_array) {
  VtkXmlReader reader(source, label_array);
  return reader.read();
}

}  // namespace incise::io_detail
