#include <fmt/format.h>

#include <limits>

#include "readers.hpp"

namespace incise::io_detail {

void MeshBuilder::add_point(long long tag, const Vec3& point) {
  if (!point.allFinite()) {
    source_->fail("point " + std::to_string(tag) + " has a NaN or infinite coordinate");
  }
  // Nothing simulated is 10^30 m (or mm) across; beyond it, volumes (cubes of lengths) and
  // squared lengths overflow to infinity and NaN, so such a point is refused here.
  constexpr double kLargestCoordinate = 1e30;
  if (point.cwiseAbs().maxCoeff() > kLargestCoordinate) {
    source_->fail("point " + std::to_string(tag) + " has a coordinate of magnitude " +
                  fmt::format("{:g}", point.cwiseAbs().maxCoeff()) + ", beyond " +
                  fmt::format("{:g}", kLargestCoordinate));
  }
  const auto index = static_cast<VertexId>(mesh_.points.size());
  if (implicit_first_ < 0) {
    if (!tag_to_index_.emplace(tag, index).second) {
      source_->fail("point tag " + std::to_string(tag) + " appears twice");
    }
  }
  mesh_.points.push_back(point);
}

VertexId MeshBuilder::index_of(long long tag, const std::string& context) const {
  if (implicit_first_ >= 0) {
    const long long index = tag - implicit_first_;
    if (index < 0 || index >= static_cast<long long>(mesh_.points.size())) {
      source_->fail(
          context + " refers to point " + std::to_string(tag) + ", but points are numbered " +
          std::to_string(implicit_first_) + " to " +
          std::to_string(implicit_first_ + static_cast<long long>(mesh_.points.size()) - 1));
    }
    return static_cast<VertexId>(index);
  }
  const auto it = tag_to_index_.find(tag);
  if (it == tag_to_index_.end()) {
    source_->fail(context + " refers to point " + std::to_string(tag) + ", which is not defined");
  }
  return it->second;
}

void MeshBuilder::add_tet(const std::array<long long, 4>& tags, long long label) {
  Tet tet;
  for (int i = 0; i < 4; ++i) {
    tet[i] = index_of(tags[i], "tetrahedron " + std::to_string(mesh_.tets.size()));
    for (int j = 0; j < i; ++j) {
      if (tet[j] == tet[i]) {
        source_->fail("tetrahedron " + std::to_string(mesh_.tets.size()) + " uses point " +
                      std::to_string(tags[i]) + " twice");
      }
    }
  }
  if (label < std::numeric_limits<int>::min() || label > std::numeric_limits<int>::max()) {
    source_->fail("tetrahedron " + std::to_string(mesh_.tets.size()) + ": region label " +
                  std::to_string(label) + " is out of range");
  }
  mesh_.tets.push_back(tet);
  mesh_.tet_labels.push_back(static_cast<int>(label));
}

void MeshBuilder::add_triangle(const std::array<long long, 3>& tags) {
  Triangle triangle;
  for (int i = 0; i < 3; ++i) {
    triangle[i] = index_of(tags[i], "triangle " + std::to_string(mesh_.triangles.size()));
  }
  mesh_.triangles.push_back(triangle);
}

RawMesh MeshBuilder::finish(MeshFormat format) {
  for (const auto& [kind, count] : skipped_) {
    if (count == 0) {
      continue;
    }
    mesh_.notes.push_back("skipped " + std::to_string(count) + " " + kind);
  }
  mesh_.format = format;
  return std::move(mesh_);
}

std::string vtk_cell_name(int type) {
  switch (type) {
    case 1:
      return "vertex cells";
    case 3:
      return "line cells";
    case 4:
      return "polyline cells";
    case 5:
      return "triangles";
    case 6:
      return "triangle strips";
    case 7:
      return "polygons";
    case 9:
      return "quads";
    case 10:
      return "tetrahedra";
    case 12:
      return "hexahedra";
    case 13:
      return "wedges";
    case 14:
      return "pyramids";
    case 22:
      return "quadratic triangles";
    case 24:
      return "quadratic tetrahedra";
    default:
      return "cells of VTK type " + std::to_string(type);
  }
}

}  // namespace incise::io_detail
