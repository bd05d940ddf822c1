#include "incise/xfem/virtual_mesh.hpp"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <unordered_set>

#include "incise/core/error.hpp"
#include "incise/mesh/disjoint_sets.hpp"

namespace incise {
VirtualMesh build_virtual_mesh(const TetMesh& mesh, std::span<const std::optional<ElementCut>> cuts,
                               std::span<const TetId> front, double min_fraction) {
  INCISE_ASSERT(min_fraction >= 0.0 && min_fraction < 0.5, "a minimum fraction in [0, 0.5)");
  INCISE_ASSERT(cuts.size() == mesh.tet_count(), "one cut entry per tetrahedron");
  const std::size_t vertices = mesh.vertex_count();
  VirtualMesh body;
  body.rest_positions.assign(mesh.rest_positions().begin(), mesh.rest_positions().end());
  body.original_of.resize(vertices);
  std::iota(body.original_of.begin(), body.original_of.end(), VertexId{0});
  body.first_copy = vertices;

  // Tie the ends of every crossed edge that a front tetrahedron holds: the cut is open only
  // where it has crossed every element around.
  std::unordered_set<std::uint64_t> front_edges;
  for (TetId t : front) {
    const Tet& tet = mesh.tet(t);
    for (const auto& edge : tet_local::kEdges) {
      front_edges.insert(
          edge_key(tet[static_cast<std::size_t>(edge[0])], tet[static_cast<std::size_t>(edge[1])]));
    }
  }
  std::vector<bool> tied(vertices, false);
  for (std::size_t t = 0; t < cuts.size() && !front_edges.empty(); ++t) {
    if (!cuts[t] || !cuts[t]->splits()) {
      continue;
    }
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    for (const auto& edge : tet_local::kEdges) {
      const auto i = static_cast<std::size_t>(edge[0]);
      const auto j = static_cast<std::size_t>(edge[1]);
      if (cuts[t]->on_b[i] != cuts[t]->on_b[j] && front_edges.contains(edge_key(tet[i], tet[j]))) {
        tied[static_cast<std::size_t>(tet[i])] = true;
        tied[static_cast<std::size_t>(tet[j])] = true;
      }
    }
  }

  std::vector<VertexId> copy(vertices, kInvalidId);
  const auto copy_of = [&](VertexId v) {
    const auto index = static_cast<std::size_t>(v);
    if (tied[index]) {
      return v;
    }
    if (copy[index] == kInvalidId) {
      copy[index] = static_cast<VertexId>(body.rest_positions.size());
      body.rest_positions.push_back(mesh.rest_position(v));
      body.original_of.push_back(v);
    }
    return copy[index];
  };

  for (std::size_t t = 0; t < cuts.size(); ++t) {
    const auto id = static_cast<TetId>(t);
    const Tet& tet = mesh.tet(id);
    if (!cuts[t] || !cuts[t]->splits()) {
      body.elements.push_back(tet);
      body.rest_tet.push_back(id);
      body.fraction.push_back(1.0);
      continue;
    }
    const SideVolumes volumes = side_volumes(rest_corners(mesh, id), *cuts[t]);
    const Tet copies = {copy_of(tet[0]), copy_of(tet[1]), copy_of(tet[2]), copy_of(tet[3])};
    const VirtualElements split = virtual_elements(tet, *cuts[t], copies);
    double fraction_a = volumes.fraction_a();
    if (fraction_a < min_fraction || 1.0 - fraction_a < min_fraction) {
      fraction_a = std::clamp(fraction_a, min_fraction, 1.0 - min_fraction);
      ++body.raised;
    }
    body.elements.push_back(split.a);
    body.rest_tet.push_back(id);
    body.fraction.push_back(fraction_a);
    body.elements.push_back(split.b);
    body.rest_tet.push_back(id);
    body.fraction.push_back(1.0 - fraction_a);
    ++body.split;
  }
  for (std::size_t v = 0; v < vertices; ++v) {
    body.tied += tied[v] ? 1 : 0;
  }
  return body;
}

SurfaceCuts cuts_by_surface(const TetMesh& mesh, std::span<const std::array<Vec3, 3>> triangles) {
  SurfaceCuts result;
  result.cuts.resize(mesh.tet_count());
  if (triangles.empty()) {
    return result;
  }
  Vec3 low = triangles[0][0];
  Vec3 high = triangles[0][0];
  for (const auto& triangle : triangles) {
    for (const Vec3& p : triangle) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
  }
  std::vector<std::array<Vec3, 3>> near;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto x = rest_corners(mesh, static_cast<TetId>(t));
    const Vec3 tet_low = x[0].cwiseMin(x[1]).cwiseMin(x[2]).cwiseMin(x[3]);
    const Vec3 tet_high = x[0].cwiseMax(x[1]).cwiseMax(x[2]).cwiseMax(x[3]);
    if ((tet_high.array() < low.array()).any() || (tet_low.array() > high.array()).any()) {
      continue;
    }
    near.clear();
    for (const auto& triangle : triangles) {
      const Vec3 triangle_low = triangle[0].cwiseMin(triangle[1]).cwiseMin(triangle[2]);
      const Vec3 triangle_high = triangle[0].cwiseMax(triangle[1]).cwiseMax(triangle[2]);
      if (!((tet_high.array() < triangle_low.array()).any() ||
            (tet_low.array() > triangle_high.array()).any())) {
        near.push_back(triangle);
      }
    }
    std::uint8_t crossed = 0;
    result.cuts[t] = cut_by_surface(x, near, &crossed);
    if (!result.cuts[t] && crossed != 0) {
      result.front.push_back(static_cast<TetId>(t));
    }
  }
  return result;
}

std::vector<int> virtual_pieces(const VirtualMesh& body, int* count) {
  DisjointSets sets(body.rest_positions.size());
  for (std::size_t e = 0; e < body.elements.size(); ++e) {
    if (!(body.fraction[e] > 0.0)) {
      continue;
    }
    for (VertexId v : body.elements[e]) {
      sets.join(v, body.elements[e][0]);
    }
  }
  std::vector<int> piece_of_root(body.rest_positions.size(), -1);
  int pieces = 0;
  std::vector<int> pieces_of_elements(body.elements.size(), -1);
  for (std::size_t e = 0; e < body.elements.size(); ++e) {
    if (!(body.fraction[e] > 0.0)) {
      continue;
    }
    int& piece = piece_of_root[static_cast<std::size_t>(sets.find(body.elements[e][0]))];
    if (piece < 0) {
      piece = pieces++;
    }
    pieces_of_elements[e] = piece;
  }
  if (count != nullptr) {
    *count = pieces;
  }
  return pieces_of_elements;
}

double material_volume(const VirtualMesh& body, const TetMesh& mesh) {
  double volume = 0.0;
  for (std::size_t e = 0; e < body.elements.size(); ++e) {
    volume += body.fraction[e] * signed_volume(mesh, body.rest_tet[e]);
  }
  return volume;
}

}  // namespace incise
