// VTK legacy .vtk reader (UNSTRUCTURED_GRID and POLYDATA; ASCII and big-endian BINARY; the
// classic CELLS layout and the OFFSETS/CONNECTIVITY layout of file version 5.1). VTK itself
// would parse this, but it is a 200 MB dependency for one function.

#include <cmath>
#include <set>
#include <string>

#include "readers.hpp"

namespace incise::io_detail {
namespace {

/// One CELLS / POLYGONS block: cell i uses connectivity[offsets[i] .. offsets[i+1]).
struct CellBlock {
  std::vector<long long> offsets{0};
  std::vector<long long> connectivity;
  [[nodiscard]] std::size_t size() const { return offsets.size() - 1; }
};

class VtkLegacyReader {
 public:
  VtkLegacyReader(Source& source, std::string label_array)
      : source_(source), builder_(source), label_array_(std::move(label_array)) {}

  RawMesh read() {
    const std::string_view magic = source_.rest_of_line();
    if (magic.find("# vtk DataFile") != 0) {
      source_.fail("a legacy VTK file starts with '# vtk DataFile Version'");
    }
    source_.skip_line();  // title
    const std::string encoding = lowercase(source_.token("ASCII or BINARY"));
    if (encoding != "ascii" && encoding != "binary") {
      source_.fail("expected ASCII or BINARY, found '" + encoding + "'");
    }
    binary_ = encoding == "binary";
    source_.expect("DATASET");
    const std::string dataset(source_.token("dataset type"));
    if (dataset != "UNSTRUCTURED_GRID" && dataset != "POLYDATA") {
      source_.fail("only UNSTRUCTURED_GRID and POLYDATA datasets hold a mesh, found " + dataset);
    }
    bool has_points = false;
    CellBlock cells;
    std::vector<long long> cell_types;
    bool has_cells = false;
    std::string attributes;  // POINT_DATA or CELL_DATA: where the geometry ends
    for (;;) {
      const std::string_view keyword = source_.next_token();
      if (keyword.empty()) {
        break;
      }
      if (keyword == "POINT_DATA" || keyword == "CELL_DATA") {
        attributes = keyword;
        break;
      }
      if (keyword == "POINTS") {
        read_points();
        has_points = true;
      } else if (keyword == "METADATA") {
        skip_metadata();
      } else if (keyword == "FIELD") {
        skip_field();
      } else if (keyword == "CELLS" || keyword == "POLYGONS" || keyword == "TRIANGLE_STRIPS" ||
                 keyword == "VERTICES" || keyword == "LINES") {
        if (!has_points) {
          source_.fail(std::string(keyword) + " before POINTS");
        }
        const std::string name(keyword);
        CellBlock block = read_cells(name);
        if (name == "CELLS") {
          cells = std::move(block);
          has_cells = true;
        } else if (name == "POLYGONS") {
          add_polygons(block, false);
        } else if (name == "TRIANGLE_STRIPS") {
          add_polygons(block, true);
        } else {
          builder_.skip(name == "LINES" ? "line cells" : "vertex cells", block.size());
        }
      } else if (keyword == "CELL_TYPES") {
        const std::size_t count = source_.count("cell type count", kMaxCount);
        end_of_header_line();
        cell_types = read_integers(count, "int", "cell types");
      } else {
        source_.fail("unexpected keyword '" + std::string(keyword) + "'");
      }
    }
    if (!has_points) {
      source_.fail_without_line("no POINTS section");
    }
    if (has_cells) {
      if (cell_types.size() != cells.size()) {
        source_.fail("CELL_TYPES lists " + std::to_string(cell_types.size()) + " types for " +
                     std::to_string(cells.size()) + " cells");
      }
      if (attributes.empty() && !label_array_.empty()) {
        source_.fail_without_line("no cell data, so no array named '" + label_array_ +
                                  "' for region labels");
      }
      const std::vector<double> labels =
          attributes.empty() ? std::vector<double>{} : cell_labels(attributes, cells.size());
      for (std::size_t c = 0; c < cells.size(); ++c) {
        add_cell(cell_types[c], cells, c,
                 labels.size() == cells.size() ? static_cast<long long>(labels[c]) : 0);
      }
    }
    return builder_.finish(MeshFormat::kVtkLegacy);
  }

 private:
  void read_points() {
    const std::size_t count = source_.count("point count", kMaxCount);
    const std::string type(source_.token("point data type"));
    end_of_header_line();
    const std::vector<double> xyz = read_reals(3 * count, type, "point coordinates");
    builder_.set_implicit_tags(0);
    for (std::size_t i = 0; i < count; ++i) {
      builder_.add_point(static_cast<long long>(i),
                         Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]));
    }
  }

  /// FIELD name n, then n arrays "name components tuples type" with their values (ParaView
  /// writes TIME and CYCLE this way right after DATASET). Calls visit(name, components,
  /// tuples, type, values) for each array; `skip_field` keeps none of them.
  template <typename Visit>
  void read_field(Visit visit) {
    (void)source_.token("field name");
    const std::size_t arrays = source_.count("field array count", 10000);
    for (std::size_t a = 0; a < arrays; ++a) {
      const std::string name(source_.token("field array name"));
      const std::size_t components = source_.count("field components", 1000000);
      const std::size_t tuples = source_.count("field tuples", kMaxCount);
      const std::string type(source_.token("field data type"));
      end_of_header_line();
      if (type == "string") {
        source_.fail("string arrays in FIELD data are not supported");
      }
      visit(name, components, tuples, type, read_reals(components * tuples, type, "FIELD data"));
      if (source_.peek_token() == "METADATA") {
        (void)source_.next_token();
        skip_metadata();
      }
    }
  }
  void skip_field() {
    read_field([](const std::string&, std::size_t, std::size_t, const std::string&,
                  const std::vector<double>&) {});
  }

  /// Binary data starts right after the line of its header; ASCII data may follow anywhere.
  void end_of_header_line() {
    if (binary_) {
      source_.skip_line();
    }
  }

  void skip_metadata() {
    // METADATA blocks end at the first empty line.
    source_.skip_line();
    while (!source_.at_end()) {
      const std::string_view line = source_.rest_of_line();
      if (line.find_first_not_of(" \t\r") == std::string_view::npos) {
        return;
      }
    }
  }

  CellBlock read_cells(const std::string& keyword) {
    const std::size_t first = source_.count("cell count", kMaxCount);
    const std::size_t second = source_.count("cell list size", kMaxCount);
    end_of_header_line();
    CellBlock block;
    if (source_.peek_token() == "OFFSETS") {
      // File version 5.1: first = offsets count (cells + 1), second = connectivity size.
      source_.expect("OFFSETS");
      const std::string offset_type(source_.token("offset type"));
      end_of_header_line();
      block.offsets = read_integers(first, offset_type, "offsets");
      source_.expect("CONNECTIVITY");
      const std::string connectivity_type(source_.token("connectivity type"));
      end_of_header_line();
      block.connectivity = read_integers(second, connectivity_type, "connectivity");
      if (block.offsets.empty() || block.offsets.front() != 0) {
        source_.fail(keyword + " offsets must start at 0");
      }
      for (std::size_t i = 1; i < block.offsets.size(); ++i) {
        if (block.offsets[i] < block.offsets[i - 1] ||
            block.offsets[i] > static_cast<long long>(block.connectivity.size())) {
          source_.fail(keyword + " offset " + std::to_string(i) + " is out of range");
        }
      }
      if (block.offsets.back() != static_cast<long long>(block.connectivity.size())) {
        source_.fail(keyword + " offsets do not cover the connectivity");
      }
      return block;
    }
    // Classic layout: per cell, its point count followed by the point ids.
    const std::vector<long long> raw = read_integers(second, "int", keyword.c_str());
    std::size_t position = 0;
    for (std::size_t c = 0; c < first; ++c) {
      if (position >= raw.size()) {
        source_.fail(keyword + ": list ends after " + std::to_string(c) + " of " +
                     std::to_string(first) + " cells");
      }
      const long long count = raw[position++];
      if (count < 0 || position + static_cast<std::size_t>(count) > raw.size()) {
        source_.fail(keyword + ": cell " + std::to_string(c) + " has a bad point count " +
                     std::to_string(count));
      }
      block.connectivity.insert(block.connectivity.end(),
                                raw.begin() + static_cast<std::ptrdiff_t>(position),
                                raw.begin() + static_cast<std::ptrdiff_t>(position + count));
      position += static_cast<std::size_t>(count);
      block.offsets.push_back(static_cast<long long>(block.connectivity.size()));
    }
    if (position != raw.size()) {
      source_.fail(keyword + ": list size " + std::to_string(raw.size()) + " does not match " +
                   std::to_string(first) + " cells");
    }
    return block;
  }

  /// Region labels from the attribute data: the first one-component integer array of
  /// CELL_DATA (SCALARS or a FIELD array). Attribute data was never needed for the mesh, so
  /// what cannot be read here leaves the tetrahedra unlabelled (with a note), not unread.
  std::vector<double> cell_labels(const std::string& first, std::size_t cell_count) {
    static const std::set<std::string> kIntegerTypes{
        "bit",          "char", "unsigned_char", "short",     "unsigned_short", "int",
        "unsigned_int", "long", "unsigned_long", "vtkIdType", "vtktypeint64",   "vtktypeuint64"};
    // The array the caller named, else the first integer one.
    const auto wanted = [&](const std::string& name, const std::string& type) {
      return label_array_.empty() ? kIntegerTypes.count(type) > 0 : name == label_array_;
    };
    std::vector<double> labels;
    try {
      std::string keyword = first;
      bool cells = false;
      std::size_t count = 0;
      while (!keyword.empty()) {
        if (keyword == "POINT_DATA" || keyword == "CELL_DATA") {
          cells = keyword == "CELL_DATA";
          count = source_.count("attribute count", kMaxCount);
        } else if (keyword == "SCALARS") {
          const std::string name(source_.token("scalars name"));
          const std::string type(source_.token("scalars type"));
          std::size_t components = 1;
          if (source_.token_on_this_line()) {
            components = source_.count("scalars components", 4);
          }
          if (source_.peek_token() == "LOOKUP_TABLE") {
            (void)source_.next_token();
            (void)source_.token("lookup table name");
          }
          end_of_header_line();
          std::vector<double> values = read_reals(components * count, type, "SCALARS");
          if (cells && labels.empty() && components == 1 && count == cell_count &&
              wanted(name, type)) {
            labels = std::move(values);
          }
        } else if (keyword == "VECTORS" || keyword == "NORMALS" || keyword == "TENSORS") {
          (void)source_.token("attribute name");
          const std::string type(source_.token("attribute type"));
          end_of_header_line();
          (void)read_reals((keyword == "TENSORS" ? 9 : 3) * count, type, keyword.c_str());
        } else if (keyword == "TEXTURE_COORDINATES") {
          (void)source_.token("attribute name");
          const std::size_t dimension = source_.count("texture dimension", 3);
          const std::string type(source_.token("attribute type"));
          end_of_header_line();
          (void)read_reals(dimension * count, type, "TEXTURE_COORDINATES");
        } else if (keyword == "FIELD") {
          read_field([&](const std::string& name, std::size_t components, std::size_t tuples,
                         const std::string& type, const std::vector<double>& values) {
            if (cells && labels.empty() && components == 1 && tuples == cell_count &&
                wanted(name, type)) {
              labels = values;
            }
          });
        } else if (keyword == "METADATA") {
          skip_metadata();
        } else {
          builder_.skip("attribute data from '" + keyword + "' on (not needed for the mesh)");
          break;
        }
        keyword = std::string(source_.next_token());
      }
    } catch (const InputError& error) {
      if (!label_array_.empty()) {
        throw;  // the caller asked for labels from here
      }
      builder_.skip(std::string("unreadable attribute data (") + error.what() + ")");
    }
    if (!label_array_.empty()) {
      if (labels.empty()) {
        source_.fail_without_line("no one-component cell array named '" + label_array_ +
                                  "' for region labels");
      }
    }
    for (double label : labels) {
      if (std::abs(label) > 2e9 || label != std::floor(label)) {
        if (label_array_.empty()) {
          builder_.skip("region labels that are not whole numbers (tetrahedra left unlabelled)");
          return {};
        }
        source_.fail_without_line("region label " + std::to_string(label) + " in '" + label_array_ +
                                  "' is not a whole number");
      }
    }
    return labels;
  }

  void add_cell(long long type, const CellBlock& cells, std::size_t c, long long label) {
    const long long begin = cells.offsets[c];
    const long long size = cells.offsets[c + 1] - begin;
    const long long* ids = cells.connectivity.data() + begin;
    if ((type == 10 && size == 4) || (type == 24 && size == 10)) {
      builder_.add_tet({ids[0], ids[1], ids[2], ids[3]}, label);
      if (type == 24) {
        builder_.skip("mid-edge nodes (kept the corners of quadratic tetrahedra)", 6);
      }
    } else if ((type == 5 && size == 3) || (type == 22 && size == 6)) {
      builder_.add_triangle({ids[0], ids[1], ids[2]});
    } else if (type == 10 || type == 5) {
      source_.fail_without_line("cell " + std::to_string(c) + " of type " + std::to_string(type) +
                                " has " + std::to_string(size) + " points");
    } else {
      builder_.skip(vtk_cell_name(static_cast<int>(type)));
    }
  }

  void add_polygons(const CellBlock& block, bool strips) {
    for (std::size_t c = 0; c < block.size(); ++c) {
      const long long begin = block.offsets[c];
      const long long size = block.offsets[c + 1] - begin;
      const long long* ids = block.connectivity.data() + begin;
      if (size < 3) {
        source_.fail_without_line("polygon " + std::to_string(c) + " has fewer than 3 points");
      }
      for (long long i = 0; i + 2 < size; ++i) {
        if (strips) {
          // Every other strip triangle is flipped to keep a consistent orientation.
          builder_.add_triangle(i % 2 == 0 ? std::array{ids[i], ids[i + 1], ids[i + 2]}
                                           : std::array{ids[i + 1], ids[i], ids[i + 2]});
        } else {
          builder_.add_triangle({ids[0], ids[i + 1], ids[i + 2]});
        }
      }
    }
  }

  static int type_size(const std::string& type) {
    if (type == "unsigned_char" || type == "char" || type == "bit") {
      return 1;
    }
    if (type == "unsigned_short" || type == "short") {
      return 2;
    }
    if (type == "unsigned_int" || type == "int" || type == "float") {
      return 4;
    }
    if (type == "unsigned_long" || type == "long" || type == "double" || type == "vtktypeint64" ||
        type == "vtktypeuint64") {
      return 8;
    }
    return 0;
  }

  /// One binary value of a VTK type, big-endian, as double.
  double binary_value(const std::string& type, const char* what) {
    const bool swap = kHostIsLittleEndian;
    if (type == "float") {
      return source_.binary<float>(swap, what);
    }
    if (type == "double") {
      return source_.binary<double>(swap, what);
    }
    if (type == "int") {
      return source_.binary<std::int32_t>(swap, what);
    }
    if (type == "unsigned_int") {
      return source_.binary<std::uint32_t>(swap, what);
    }
    if (type == "long" || type == "vtktypeint64") {
      return static_cast<double>(source_.binary<std::int64_t>(swap, what));
    }
    if (type == "unsigned_long" || type == "vtktypeuint64") {
      return static_cast<double>(source_.binary<std::uint64_t>(swap, what));
    }
    if (type == "short") {
      return source_.binary<std::int16_t>(swap, what);
    }
    if (type == "unsigned_short") {
      return source_.binary<std::uint16_t>(swap, what);
    }
    if (type == "char") {
      return source_.binary<std::int8_t>(swap, what);
    }
    return source_.binary<std::uint8_t>(swap, what);
  }

  std::vector<double> read_reals(std::size_t count, const std::string& type, const char* what) {
    if (type_size(type) == 0) {
      source_.fail("unknown data type '" + type + "'");
    }
    source_.require_room(count, binary_ ? static_cast<std::size_t>(type_size(type)) : 0, what);
    std::vector<double> values(count);
    for (double& value : values) {
      value = binary_ ? binary_value(type, what) : source_.real(what);
      if (!std::isfinite(value)) {
        source_.fail_without_line(std::string("non-finite value in ") + what);
      }
    }
    return values;
  }

  std::vector<long long> read_integers(std::size_t count, const std::string& type,
                                       const char* what) {
    if (type_size(type) == 0 || type == "float" || type == "double") {
      source_.fail("'" + type + "' is not an integer type for " + what);
    }
    source_.require_room(count, binary_ ? static_cast<std::size_t>(type_size(type)) : 0, what);
    std::vector<long long> values(count);
    for (long long& value : values) {
      value = binary_ ? static_cast<long long>(binary_value(type, what)) : source_.integer(what);
    }
    return values;
  }

  Source& source_;
  MeshBuilder builder_;
  bool binary_ = false;
  std::string label_array_;
};

}  // namespace

RawMesh read_vtk_legacy(Source& source, const std::string& label_array) {
  VtkLegacyReader reader(source, label_array);
  return reader.read();
}

}  // namespace incise::io_detail
