#include "incise/mesh/used_points.hpp"

#include <utility>

namespace incise {

UsedPoints used_points(std::span<const Tet> tets, std::size_t point_count) {
  UsedPoints used{std::vector<VertexId>(point_count, kInvalidId), 0};
  for (const Tet& tet : tets) {
    for (VertexId v : tet) {
      used.index[static_cast<std::size_t>(v)] = 0;
    }
  }
  for (VertexId& index : used.index) {
    if (index != kInvalidId) {
      index = static_cast<VertexId>(used.count++);
    }
  }
  return used;
}

std::vector<VertexId> drop_unused_points(std::vector<Vec3>& points, std::vector<Tet>& tets) {
  const std::vector<VertexId> remap = used_points(tets, points.size()).index;
  std::vector<Vec3> kept;
  kept.reserve(points.size());
  for (std::size_t v = 0; v < points.size(); ++v) {
    if (remap[v] != kInvalidId) {
      kept.push_back(points[v]);
    }
  }
  for (Tet& tet : tets) {
    for (VertexId& v : tet) {
      v = remap[static_cast<std::size_t>(v)];
    }
  }
  points = std::move(kept);
  return remap;
}

}  // namespace incise
