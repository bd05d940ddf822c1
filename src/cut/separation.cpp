#include "incise/cut/separation.hpp"

#include <algorithm>
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
  // The star is small (tens of tetrahedra) and this runs for hundreds of vertices a pose:
  // sorted vectors, not maps.
  std::vector<std::pair<TetId, std::size_t>> index(around.size());
  for (std::size_t i = 0; i < around.size(); ++i) {
    index[i] = {around[i], i};
  }
  std::sort(index.begin(), index.end());
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
      const auto it =
          std::lower_bound(index.begin(), index.end(), std::pair<TetId, std::size_t>{neighbor, 0});
      if (it != index.end() && it->first == neighbor) {
        parent[find(i)] = find(it->second);
      }
    }
  }
  // The groups in the order of their roots' indices, each in the star's order.
  std::vector<std::pair<std::size_t, TetId>> by_root(around.size());
  for (std::size_t i = 0; i < around.size(); ++i) {
    by_root[i] = {find(i), around[i]};
  }
  std::stable_sort(by_root.begin(), by_root.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  if (by_root.front().first == by_root.back().first) {
    return {};  // one group: nothing to separate
  }
  std::vector<VertexId> copies;
  std::vector<TetId> tets;
  for (std::size_t k = 0; k < by_root.size();) {
    tets.clear();
    const std::size_t root = by_root[k].first;
    for (; k < by_root.size() && by_root[k].first == root; ++k) {
      tets.push_back(by_root[k].second);
    }
    if (root != by_root.front().first) {  // the group of the lowest root keeps the vertex
      copies.push_back(mesh.duplicate_vertex(vertex, tets));
    }
  }
  return copies;
}

std::vector<std::pair<VertexId, VertexId>> pinched_edges(
    const TetMesh& mesh, std::span<const VertexId> vertices,
    const std::function<bool(VertexId)>& on_cut) {
  std::vector<std::pair<VertexId, VertexId>> pinched;
  std::vector<VertexId> on_boundary_faces;  // the other corners of v's boundary faces
  for (VertexId v : vertices) {
    if (static_cast<std::size_t>(v) >= mesh.vertex_count()) {
      continue;
    }
    on_boundary_faces.clear();
    for (TetId t : mesh.vertex_tets(v)) {
      const Tet& tet = mesh.tet(t);
      for (int f = 0; f < 4; ++f) {
        if (mesh.tet_neighbors(t)[f] != kBoundaryFace || f == mesh.local_index(t, v)) {
          continue;
        }
        for (int k : tet_local::kFaces[f]) {
          if (tet[k] != v) {
            on_boundary_faces.push_back(tet[k]);
          }
        }
      }
    }
    // An edge (v, w) on more than two boundary faces is pinched.
    std::sort(on_boundary_faces.begin(), on_boundary_faces.end());
    for (std::size_t k = 0; k < on_boundary_faces.size();) {
      const VertexId w = on_boundary_faces[k];
      std::size_t count = 0;
      for (; k < on_boundary_faces.size() && on_boundary_faces[k] == w; ++k) {
        ++count;
      }
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
