#include "incise/cut/separation.hpp"

#include <algorithm>
#include <map>
#include <numeric>

namespace incise {

std::vector<VertexId> separate_at_cut_faces(TetMesh& mesh, VertexId vertex,
                                            const CutFacePredicate& is_cut) {
  // Group the tetrahedra around the vertex: two are joined when they share a face through the
  // vertex that is not a cut face.
  const std::vector<TetId> around(mesh.vertex_tets(vertex).begin(), mesh.vertex_tets(vertex).end());
  if (around.size() < 2) {
    return {};
  }
  std::vector<std::size_t> parent(around.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](std::size_t i) {
    while (parent[i] != i) {
      parent[i] = parent[parent[i]];
      i = parent[i];
    }
    return i;
  };
  std::map<TetId, std::size_t> index;
  for (std::size_t i = 0; i < around.size(); ++i) {
    index[around[i]] = i;
  }
  for (std::size_t i = 0; i < around.size(); ++i) {
    const TetId t = around[i];
    const int local = mesh.local_index(t, vertex);
    for (int f = 0; f < 4; ++f) {
      if (f == local) {
        continue;  // the face opposite the vertex does not contain it
      }
      const TetId neighbor = mesh.tet_neighbors(t)[f];
      if (neighbor < 0 || neighbor < t || is_cut(t, f)) {
        continue;
      }
      const auto it = index.find(neighbor);
      if (it != index.end()) {
        parent[find(i)] = find(it->second);
      }
    }
  }
  std::map<std::size_t, std::vector<TetId>> groups;
  for (std::size_t i = 0; i < around.size(); ++i) {
    groups[find(i)].push_back(around[i]);
  }
  std::vector<VertexId> copies;
  bool first = true;
  for (auto& [root, tets] : groups) {
    if (first) {
      first = false;  // the group holding the smallest tet id keeps the vertex
      continue;
    }
    copies.push_back(mesh.duplicate_vertex(vertex, tets));
  }
  return copies;
}

std::vector<std::pair<VertexId, VertexId>> pinched_edges(
    const TetMesh& mesh, std::span<const VertexId> vertices,
    const std::function<bool(VertexId)>& on_cut) {
  std::vector<std::pair<VertexId, VertexId>> pinched;
  for (VertexId v : vertices) {
    if (static_cast<std::size_t>(v) >= mesh.vertex_count()) {
      continue;
    }
    std::map<VertexId, int> boundary_faces;
    for (TetId t : mesh.vertex_tets(v)) {
      const Tet& tet = mesh.tet(t);
      for (int f = 0; f < 4; ++f) {
        if (mesh.tet_neighbors(t)[f] != kBoundaryFace || f == mesh.local_index(t, v)) {
          continue;
        }
        for (int k : tet_local::kFaces[f]) {
          if (tet[k] != v) {
            ++boundary_faces[tet[k]];
          }
        }
      }
    }
    for (const auto& [w, count] : boundary_faces) {
      if (count > 2 && (on_cut(v) || on_cut(w))) {
        pinched.emplace_back(std::min(v, w), std::max(v, w));
      }
    }
  }
  std::sort(pinched.begin(), pinched.end());
  pinched.erase(std::unique(pinched.begin(), pinched.end()), pinched.end());
  return pinched;
}

}  // namespace incise
