#pragma once
// The graph of a mesh's edges, vertex by vertex, in compressed rows: what spring models,
// matrix patterns and breadth-first traversals all need.

#include <span>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// The mesh's vertices joined by its edges, in compressed rows (vertex_graph()).
struct VertexGraph {
  /// Neighbours of v are vertex[row_start[v] .. row_start[v + 1]), joined by edge[...] (in
  /// edge order).
  std::vector<std::size_t> row_start;
  std::vector<VertexId> vertex;  ///< neighbours, row by row
  std::vector<EdgeId> edge;      ///< the edge to each neighbour

  /// The neighbours of v.
  [[nodiscard]] std::span<const VertexId> neighbors(VertexId v) const {
    return std::span<const VertexId>(vertex).subspan(row_start[v], row_start[v + 1] - row_start[v]);
  }
};

[[nodiscard]] VertexGraph vertex_graph(const TetMesh& mesh);
/// The same into an existing graph, reusing its storage (a cut rebuilds it every frame: fresh
/// arrays would be faulted in anew each time).
void vertex_graph(const TetMesh& mesh, VertexGraph& graph);

}  // namespace incise
