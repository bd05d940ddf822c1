#pragma once
// Per-format readers and the bookkeeping they share. Private to the io module.

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <unordered_map>

#include "incise/io/mesh_io.hpp"
#include "source.hpp"

namespace incise::io_detail {

/// The most items a count in a file may announce (int32, as VTK and Gmsh store them): a larger
/// one is a damaged file, refused before anything is allocated for it.
inline constexpr std::size_t kMaxCount = std::numeric_limits<std::int32_t>::max();

/// Collects cells, maps file node tags to point indices, and counts what it skipped.
class MeshBuilder {
 public:
  explicit MeshBuilder(Source& source) : source_(&source) {}
  /// Errors from now on name this file (formats split over two files).
  void set_source(Source& source) { source_ = &source; }

  /// Registers a point under a file tag; a repeated tag is an error.
  void add_point(long long tag, const Vec3& point);
  [[nodiscard]] std::size_t point_count() const { return mesh_.points.size(); }
  /// Point index of a file tag; fails with the current line if the tag is unknown.
  [[nodiscard]] VertexId index_of(long long tag, const std::string& context) const;
  /// Points are numbered 0..n-1 by position in the file (tags are implicit).
  void set_implicit_tags(long long first_tag) { implicit_first_ = first_tag; }

  /// A tetrahedron in region `label` (a physical group, subdomain or reference; 0: none).
  void add_tet(const std::array<long long, 4>& tags, long long label = 0);
  void add_triangle(const std::array<long long, 3>& tags);
  /// Notes a skipped cell of a kind ("hexahedra", "lines" ...).
  void skip(const std::string& kind, std::size_t count = 1) { skipped_[kind] += count; }

  RawMesh finish(MeshFormat format);

 private:
  Source* source_;
  RawMesh mesh_;
  std::unordered_map<long long, VertexId> tag_to_index_;
  long long implicit_first_ = -1;
  std::map<std::string, std::size_t> skipped_;
};

RawMesh read_gmsh(Source& source);
RawMesh read_tetgen(Source& node_source, Source* ele_source);
RawMesh read_medit(Source& source);
/// `label_array`: the cell array to take as region labels (empty: the first integer one).
RawMesh read_vtk_legacy(Source& source, const std::string& label_array = {});
RawMesh read_vtk_xml(Source& source, const std::string& label_array = {});
RawMesh read_obj(Source& source);
RawMesh read_off(Source& source);
RawMesh read_stl(Source& source);
RawMesh read_ply(Source& source);

/// Name of a VTK cell type for notes ("hexahedron", "cell type 42").
std::string vtk_cell_name(int type);

}  // namespace incise::io_detail
