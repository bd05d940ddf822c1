#include "incise/mesh/vertex_graph.hpp"

namespace incise {

VertexGraph vertex_graph(const TetMesh& mesh) {
  VertexGraph graph;
  vertex_graph(mesh, graph);
  return graph;
}

void vertex_graph(const TetMesh& mesh, VertexGraph& graph) {
  const std::size_t n = mesh.vertex_count();
  graph.row_start.assign(n + 1, 0);
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& ends = mesh.edge(static_cast<EdgeId>(e));
    ++graph.row_start[ends[0] + 1];
    ++graph.row_start[ends[1] + 1];
  }
  for (std::size_t v = 0; v < n; ++v) {
    graph.row_start[v + 1] += graph.row_start[v];
  }
  graph.vertex.resize(graph.row_start[n]);
  graph.edge.resize(graph.row_start[n]);
  std::vector<std::size_t> fill(graph.row_start.begin(), graph.row_start.end() - 1);
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& ends = mesh.edge(static_cast<EdgeId>(e));
    for (int side = 0; side < 2; ++side) {
      const std::size_t slot = fill[ends[side]]++;
      graph.vertex[slot] = ends[1 - side];
      graph.edge[slot] = static_cast<EdgeId>(e);
    }
  }
}

}  // namespace incise
