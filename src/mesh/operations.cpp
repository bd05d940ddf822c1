#include "incise/mesh/operations.hpp"

#include <algorithm>
#include <string>
#include <vector>

#include "incise/core/error.hpp"

namespace incise {

VertexId split_edge(TetMesh& mesh, EdgeId edge, double t) {
  if (edge < 0 || static_cast<std::size_t>(edge) >= mesh.edge_count()) {
    throw InputError("split_edge: edge " + std::to_string(edge) + " does not exist");
  }
  if (!(t > 0.0 && t < 1.0)) {
    throw InputError("split_edge: the split point must lie strictly inside the edge");
  }
  const auto [a, b] = mesh.edge(edge);
  const std::array<VertexId, 2> parents{a, b};
  const std::array<double, 2> weights{1.0 - t, t};
  const VertexId middle = mesh.add_vertex(parents, weights);
  // Copy: the list changes as the tetrahedra around the edge are replaced.
  const std::vector<TetId> around(mesh.edge_tets(edge).begin(), mesh.edge_tets(edge).end());
  for (TetId tet : around) {
    Tet near_a = mesh.tet(tet);
    Tet near_b = mesh.tet(tet);
    std::replace(near_a.begin(), near_a.end(), b, middle);
    std::replace(near_b.begin(), near_b.end(), a, middle);
    const std::array<Tet, 2> children{near_a, near_b};
    mesh.replace_tet(tet, children);
  }
  return middle;
}

VertexId split_face(TetMesh& mesh, TetId tet, int local_face,
                    const std::array<double, 3>& weights) {
  if (tet < 0 || static_cast<std::size_t>(tet) >= mesh.tet_count() || local_face < 0 ||
      local_face > 3) {
    throw InputError("split_face: no such tetrahedron face");
  }
  const auto& local = tet_local::kFaces[local_face];
  const std::array<VertexId, 3> face{mesh.tet(tet)[local[0]], mesh.tet(tet)[local[1]],
                                     mesh.tet(tet)[local[2]]};
  const TetId neighbor = mesh.tet_neighbors(tet)[local_face];
  if (neighbor == kNonManifoldFace) {
    throw InputError("split_face: the face is shared by more than two tetrahedra");
  }
  const VertexId point = mesh.add_vertex(face, weights);
  std::vector<TetId> sides{tet};
  if (neighbor >= 0) {
    sides.push_back(neighbor);
  }
  for (TetId side : sides) {
    std::array<Tet, 3> children;
    for (int k = 0; k < 3; ++k) {
      children[k] = mesh.tet(side);
      std::replace(children[k].begin(), children[k].end(), face[k], point);
    }
    mesh.replace_tet(side, children);
  }
  return point;
}

VertexId split_tet(TetMesh& mesh, TetId tet, const std::array<double, 4>& weights) {
  if (tet < 0 || static_cast<std::size_t>(tet) >= mesh.tet_count()) {
    throw InputError("split_tet: tetrahedron " + std::to_string(tet) + " does not exist");
  }
  const Tet parent = mesh.tet(tet);
  const VertexId point = mesh.add_vertex(parent, weights);
  std::array<Tet, 4> children;
  for (int i = 0; i < 4; ++i) {
    children[i] = parent;
    children[i][i] = point;
  }
  mesh.replace_tet(tet, children);
  return point;
}

}  // namespace incise
