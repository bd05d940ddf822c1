// Gmsh .msh reader: versions 1, 2.x (ASCII and binary), 4.0 (ASCII) and 4.1 (ASCII and
// binary). Written here because no Debian library parses every version without pulling in
// Gmsh's global model state, and we want errors that name the line.

#include <array>
#include <map>

#include "readers.hpp"

namespace incise::io_detail {
namespace {

/// Nodes per element for Gmsh element types 1..31 (0 = unknown).
int nodes_per_element(long long type) {
  static constexpr std::array<int, 32> kNodes = {0,  2,  3,  4,  4, 8, 6,  5,  3,  6, 9,
                                                 10, 27, 18, 14, 1, 8, 20, 15, 13, 9, 10,
                                                 12, 15, 15, 21, 4, 5, 6,  20, 35, 56};
  return type >= 1 && type < static_cast<long long>(kNodes.size()) ? kNodes[type] : 0;
}

std::string element_kind(long long type) {
  switch (type) {
    case 1:
    case 8:
    case 26:
    case 27:
    case 28:
      return "line elements";
    case 3:
    case 10:
    case 16:
      return "quadrangles";
    case 5:
    case 12:
    case 17:
      return "hexahedra";
    case 6:
    case 13:
    case 18:
      return "prisms";
    case 7:
    case 14:
    case 19:
      return "pyramids";
    case 15:
      return "point elements";
    default:
      return "elements of Gmsh type " + std::to_string(type);
  }
}

struct GmshReader {
  Source& source;
  MeshBuilder builder;
  double version = 1.0;
  bool binary = false;
  bool swap = false;
  int size_t_bytes = 8;
  std::size_t corner_only_tets = 0;
  std::size_t corner_only_triangles = 0;

  explicit GmshReader(Source& input) : source(input), builder(input) {}

  /// Keeps tetrahedra (linear, or the corners of 10-node ones) and triangles; skips the rest.
  void element(long long type, const long long* nodes, long long label = 0) {
    if (type == 4 || type == 11) {
      builder.add_tet({nodes[0], nodes[1], nodes[2], nodes[3]}, label);
      corner_only_tets += type == 11 ? 1 : 0;
    } else if (type == 2 || type == 9) {
      builder.add_triangle({nodes[0], nodes[1], nodes[2]});
      corner_only_triangles += type == 9 ? 1 : 0;
    } else {
      builder.skip(element_kind(type));
    }
  }

  std::size_t binary_size(const char* what) {
    if (size_t_bytes == 8) {
      const auto value = source.binary<std::uint64_t>(swap, what);
      if (value > kMaxCount) {
        source.fail_without_line(std::string(what) + " " + std::to_string(value) +
                                 " is out of range");
      }
      return static_cast<std::size_t>(value);
    }
    return source.binary<std::uint32_t>(swap, what);
  }

  void read_header() {
    version = source.real("format version");
    const long long file_type = source.integer("file type");
    const long long data_size = source.integer("data size");
    if (version < 2.0 || version >= 5.0) {
      source.fail("unsupported Gmsh format version " + std::to_string(version));
    }
    if (file_type != 0 && file_type != 1) {
      source.fail("file type must be 0 (ASCII) or 1 (binary), found " + std::to_string(file_type));
    }
    if (data_size != 8 && data_size != 4) {
      source.fail("unsupported data size " + std::to_string(data_size));
    }
    size_t_bytes = static_cast<int>(data_size);
    binary = file_type == 1;
    source.skip_line();
    if (binary) {
      if (version >= 4.0 && version < 4.1) {
        source.fail("binary Gmsh 4.0 files are not supported; re-save as 4.1 or 2.2");
      }
      const auto one = source.binary<std::int32_t>(false, "endianness marker");
      if (one != 1) {
        if (Source::byte_swapped(one) != 1) {
          source.fail_without_line("bad endianness marker in binary header");
        }
        swap = true;
      }
    }
    source.expect("$EndMeshFormat");
  }

  void skip_section(std::string_view name) {
    // $Foo ends at $EndFoo (version 1 uses $ENDFOO).
    std::string end = "$End" + std::string(name.substr(1));
    const std::size_t found = source.bytes().find(end, source.offset());
    if (found == std::string_view::npos) {
      source.fail("section " + std::string(name) + " has no " + end);
    }
    source.seek(found + end.size());
  }

  void read_nodes_v1_v2() {
    const std::size_t count = source.count("node count", kMaxCount);
    if (binary) {
      source.skip_line();
      for (std::size_t i = 0; i < count; ++i) {
        const auto tag = source.binary<std::int32_t>(swap, "node tag");
        double xyz[3];
        for (double& c : xyz) {
          c = source.binary<double>(swap, "node coordinate");
        }
        builder.add_point(tag, Vec3(xyz[0], xyz[1], xyz[2]));
      }
      return;
    }
    for (std::size_t i = 0; i < count; ++i) {
      const long long tag = source.integer("node tag");
      const double x = source.real("x");
      const double y = source.real("y");
      const double z = source.real("z");
      builder.add_point(tag, Vec3(x, y, z));
    }
  }

  void read_elements_v1_v2(bool version1) {
    const std::size_t count = source.count("element count", kMaxCount);
    long long nodes[64];
    if (binary) {
      source.skip_line();
      std::size_t read = 0;
      while (read < count) {
        const auto type = source.binary<std::int32_t>(swap, "element type");
        const auto in_block = source.binary<std::int32_t>(swap, "elements in block");
        const auto tags = source.binary<std::int32_t>(swap, "tag count");
        const int node_count = nodes_per_element(type);
        if (node_count == 0 || in_block < 0 || tags < 0 || tags > 64 ||
            read + static_cast<std::size_t>(in_block) > count) {
          source.fail_without_line("bad binary element block header (type " + std::to_string(type) +
                                   ")");
        }
        for (int e = 0; e < in_block; ++e) {
          (void)source.binary<std::int32_t>(swap, "element tag");
          long long tag_values[2] = {0, 0};
          for (int t = 0; t < tags; ++t) {
            const long long value = source.binary<std::int32_t>(swap, "element tags");
            if (t < 2) {
              tag_values[t] = value;
            }
          }
          for (int n = 0; n < node_count; ++n) {
            nodes[n] = source.binary<std::int32_t>(swap, "element nodes");
          }
          element(type, nodes, region_label(tag_values[0], tag_values[1]));
        }
        read += static_cast<std::size_t>(in_block);
      }
      return;
    }
    for (std::size_t i = 0; i < count; ++i) {
      (void)source.integer("element tag");
      const long long type = source.integer("element type");
      int node_count = nodes_per_element(type);
      long long physical = 0;
      long long elementary = 0;
      if (version1) {
        physical = source.integer("physical region");
        elementary = source.integer("elementary region");
        const long long listed = source.integer("node count");
        if (node_count != 0 && listed != node_count) {
          source.fail("element of type " + std::to_string(type) + " must list " +
                      std::to_string(node_count) + " nodes, not " + std::to_string(listed));
        }
        if (listed < 0 || listed > 64) {
          source.fail("node count " + std::to_string(listed) + " is out of range");
        }
        node_count = static_cast<int>(listed);
      } else {
        const std::size_t tags = source.count("tag count", 64);
        for (std::size_t t = 0; t < tags; ++t) {
          const long long value = source.integer("element tag");
          if (t == 0) {
            physical = value;
          } else if (t == 1) {
            elementary = value;
          }
        }
      }
      if (node_count == 0) {
        builder.skip(element_kind(type));
        source.skip_line();
        continue;
      }
      for (int n = 0; n < node_count; ++n) {
        nodes[n] = source.integer("element node");
      }
      if (source.token_on_this_line()) {
        source.fail("too many nodes for an element of type " + std::to_string(type));
      }
      element(type, nodes, region_label(physical, elementary));
    }
  }

  /// A tetrahedron's region: its physical group, else its elementary entity (0: none).
  static long long region_label(long long physical, long long elementary) {
    return physical != 0 ? physical : elementary;
  }

  /// Physical group of each volume entity (from $Entities): a v4 element block names only
  /// its entity.
  std::map<long long, long long> volume_physical;

  /// $Entities (ASCII; a binary one is skipped and blocks keep their entity tags): points,
  /// curves, surfaces and volumes with their physical tags.
  void read_entities() {
    if (binary) {
      skip_section("$Entities");
      return;
    }
    const bool v41 = version >= 4.1;
    std::size_t counts[4];
    for (auto& count : counts) {
      count = source.count("entity count", kMaxCount);
    }
    for (int dimension = 0; dimension < 4; ++dimension) {
      for (std::size_t e = 0; e < counts[dimension]; ++e) {
        const long long tag = source.integer("entity tag");
        const int coordinates = dimension == 0 && v41 ? 3 : 6;
        for (int k = 0; k < coordinates; ++k) {
          (void)source.real("entity bounding box");
        }
        const std::size_t physicals = source.count("physical tag count", kMaxCount);
        long long first = 0;
        for (std::size_t k = 0; k < physicals; ++k) {
          const long long physical = source.integer("physical tag");
          if (k == 0) {
            first = physical;
          }
        }
        if (dimension > 0) {
          const std::size_t bounding = source.count("bounding entity count", kMaxCount);
          for (std::size_t k = 0; k < bounding; ++k) {
            (void)source.integer("bounding entity tag");
          }
        }
        if (dimension == 3 && physicals > 0) {
          volume_physical[tag] = first;
        }
      }
    }
    source.expect("$EndEntities");
  }

  void read_nodes_v4() {
    const bool v41 = version >= 4.1;
    std::size_t blocks = 0;
    std::size_t total = 0;
    if (binary) {
      source.skip_line();  // the binary data starts after the section line
      blocks = binary_size("entity block count");
      total = binary_size("node count");
      (void)binary_size("minimum node tag");
      (void)binary_size("maximum node tag");
    } else {
      blocks = source.count("entity block count", kMaxCount);
      total = source.count("node count", kMaxCount);
      if (v41) {
        (void)source.integer("minimum node tag");
        (void)source.integer("maximum node tag");
      }
    }
    std::size_t read = 0;
    std::vector<long long> tags;
    for (std::size_t b = 0; b < blocks; ++b) {
      long long dimension = 0;
      long long parametric = 0;
      std::size_t in_block = 0;
      if (binary) {
        dimension = source.binary<std::int32_t>(swap, "entity dimension");
        (void)source.binary<std::int32_t>(swap, "entity tag");
        parametric = source.binary<std::int32_t>(swap, "parametric flag");
        in_block = binary_size("nodes in block");
      } else if (v41) {
        dimension = source.integer("entity dimension");
        (void)source.integer("entity tag");
        parametric = source.integer("parametric flag");
        in_block = source.count("nodes in block", kMaxCount);
      } else {
        (void)source.integer("entity tag");
        dimension = source.integer("entity dimension");
        parametric = source.integer("parametric flag");
        in_block = source.count("nodes in block", kMaxCount);
      }
      if (dimension < 0 || dimension > 3) {
        source.fail("entity dimension " + std::to_string(dimension) + " is out of range");
      }
      if (read + in_block > total) {
        source.fail("node blocks hold more nodes than the " + std::to_string(total) + " announced");
      }
      const long long extra = parametric != 0 ? dimension : 0;
      source.require_room(in_block, binary ? 8 : 0, "nodes in block");
      tags.resize(in_block);
      if (v41) {
        for (auto& tag : tags) {
          tag =
              binary ? static_cast<long long>(binary_size("node tag")) : source.integer("node tag");
        }
      }
      for (std::size_t i = 0; i < in_block; ++i) {
        if (!v41) {
          tags[i] = source.integer("node tag");
        }
        double xyz[3];
        for (double& c : xyz) {
          c = binary ? source.binary<double>(swap, "node coordinate") : source.real("coordinate");
        }
        for (long long p = 0; p < extra; ++p) {
          (void)(binary ? source.binary<double>(swap, "parametric coordinate")
                        : source.real("parametric coordinate"));
        }
        builder.add_point(tags[i], Vec3(xyz[0], xyz[1], xyz[2]));
      }
      read += in_block;
    }
    if (read != total) {
      source.fail("node blocks hold " + std::to_string(read) + " nodes, but " +
                  std::to_string(total) + " were announced");
    }
  }

  void read_elements_v4() {
    const bool v41 = version >= 4.1;
    std::size_t blocks = 0;
    std::size_t total = 0;
    if (binary) {
      source.skip_line();
      blocks = binary_size("entity block count");
      total = binary_size("element count");
      (void)binary_size("minimum element tag");
      (void)binary_size("maximum element tag");
    } else {
      blocks = source.count("entity block count", kMaxCount);
      total = source.count("element count", kMaxCount);
      if (v41) {
        (void)source.integer("minimum element tag");
        (void)source.integer("maximum element tag");
      }
    }
    std::size_t read = 0;
    long long nodes[64];
    for (std::size_t b = 0; b < blocks; ++b) {
      long long type = 0;
      std::size_t in_block = 0;
      long long entity = 0;
      if (binary) {
        (void)source.binary<std::int32_t>(swap, "entity dimension");
        entity = source.binary<std::int32_t>(swap, "entity tag");
        type = source.binary<std::int32_t>(swap, "element type");
        in_block = binary_size("elements in block");
      } else if (v41) {
        (void)source.integer("entity dimension");
        entity = source.integer("entity tag");
        type = source.integer("element type");
        in_block = source.count("elements in block", kMaxCount);
      } else {
        entity = source.integer("entity tag");
        (void)source.integer("entity dimension");
        type = source.integer("element type");
        in_block = source.count("elements in block", kMaxCount);
      }
      // A file with volume physical groups labels by them; a volume in none of them is region
      // 0 (as incise writes label 0), not its entity tag. Without any: the entity tag.
      const auto physical = volume_physical.find(entity);
      const long long label = physical != volume_physical.end() ? physical->second
                              : volume_physical.empty()         ? entity
                                                                : 0;
      const int node_count = nodes_per_element(type);
      if (node_count == 0) {
        source.fail("unknown Gmsh element type " + std::to_string(type));
      }
      if (read + in_block > total) {
        source.fail("element blocks hold more elements than the " + std::to_string(total) +
                    " announced");
      }
      for (std::size_t e = 0; e < in_block; ++e) {
        if (binary) {
          (void)binary_size("element tag");
          for (int n = 0; n < node_count; ++n) {
            nodes[n] = static_cast<long long>(binary_size("element node"));
          }
        } else {
          (void)source.integer("element tag");
          for (int n = 0; n < node_count; ++n) {
            nodes[n] = source.integer("element node");
          }
          if (source.token_on_this_line()) {
            source.fail("too many nodes for an element of type " + std::to_string(type));
          }
        }
        element(type, nodes, label);
      }
      read += in_block;
    }
    if (read != total) {
      source.fail("element blocks hold " + std::to_string(read) + " elements, but " +
                  std::to_string(total) + " were announced");
    }
  }

  RawMesh read() {
    bool saw_nodes = false;
    bool saw_header = false;
    for (;;) {
      const std::string_view section = source.next_token();
      if (section.empty()) {
        break;
      }
      if (section.front() != '$') {
        source.fail("expected a section such as $Nodes, found '" + std::string(section) + "'");
      }
      if (section == "$MeshFormat") {
        read_header();
        saw_header = true;
      } else if (section == "$NOD" || section == "$Nodes") {
        if (section == "$NOD" && saw_header) {
          source.fail("$NOD (version 1) in a file that declared version " +
                      std::to_string(version));
        }
        if (saw_nodes) {
          source.fail("a second node section");
        }
        if (!saw_header || version < 4.0) {
          read_nodes_v1_v2();
        } else {
          read_nodes_v4();
        }
        source.expect(saw_header ? "$EndNodes" : "$ENDNOD");
        saw_nodes = true;
      } else if (section == "$Entities" && saw_header && version >= 4.0) {
        read_entities();
      } else if (section == "$ELM" || section == "$Elements") {
        if (!saw_nodes) {
          source.fail("elements before nodes");
        }
        if (!saw_header || version < 4.0) {
          read_elements_v1_v2(!saw_header);
        } else {
          read_elements_v4();
        }
        source.expect(saw_header ? "$EndElements" : "$ENDELM");
      } else {
        skip_section(section);
      }
    }
    if (!saw_nodes) {
      source.fail_without_line("no node section ($Nodes or $NOD)");
    }
    if (corner_only_tets > 0) {
      builder.skip("mid-edge nodes of " + std::to_string(corner_only_tets) +
                       " quadratic tetrahedra (kept their corners)",
                   corner_only_tets * 6);
    }
    if (corner_only_triangles > 0) {
      builder.skip("mid-edge nodes of quadratic triangles (kept their corners)",
                   corner_only_triangles * 3);
    }
    return builder.finish(MeshFormat::kGmsh);
  }
};

}  // namespace

RawMesh read_gmsh(Source& source) {
  GmshReader reader(source);
  return reader.read();
}

}  // namespace incise::io_detail
