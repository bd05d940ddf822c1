#pragma once
// The vertices the mesh's edits touched since a model last caught up, collected from the
// mesh's events: a model that updates only around them (the corotational FEM, the mass-spring
// model) reads marked() in its refresh() and clears it. Marked are the vertices whose
// tetrahedra, edges, rest shapes, element or edge ids, or material fractions changed: the union
// of what those models read, so each model's own rule stays a subset.
//
// Registers itself with the mesh for its lifetime; not thread-safe (edits and refresh() run on
// the simulation's thread).

#include <cstdint>
#include <span>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// The vertices the mesh's edits touched since the last clear(): a model's refresh() reads
/// them to follow the edits locally. Marks itself from the mesh's events.
class VertexMarks final : public MeshObserver {
 public:
  /// Watches `mesh` (which must outlive it).
  explicit VertexMarks(TetMesh& mesh);
  VertexMarks(const VertexMarks&) = delete;
  VertexMarks& operator=(const VertexMarks&) = delete;
  ~VertexMarks() override;

  void mark(VertexId vertex);  ///< marks one vertex (once)
  void mark(const Tet& tet);   ///< marks a tetrahedron's corners
  /// Every vertex (a model built afresh, or restored).
  void mark_all();
  void clear();  ///< unmarks every vertex
  /// The marked vertices, each once, in the order they were marked.
  [[nodiscard]] std::span<const VertexId> marked() const { return marked_; }
  /// Whether `vertex` is marked.
  [[nodiscard]] bool is_marked(VertexId vertex) const {
    return static_cast<std::size_t>(vertex) < flags_.size() &&
           flags_[static_cast<std::size_t>(vertex)] != 0;
  }
  [[nodiscard]] std::size_t size() const { return marked_.size(); }  ///< vertices marked
  [[nodiscard]] bool empty() const { return marked_.empty(); }       ///< none marked

  void on_vertex_added(const TetMesh& mesh, VertexId vertex, const VertexOrigin& origin) override;
  void on_tet_added(const TetMesh& mesh, TetId tet) override;
  void on_tet_replaced(const TetMesh& mesh, TetId parent, std::span<const TetId> children,
                       const Tet& parent_vertices) override;
  /// The removed one's vertices, and those of the last tetrahedron, which took its id.
  void on_tet_removed(const TetMesh& mesh, TetId removed, TetId moved_from,
                      const Tet& removed_vertices) override;
  void on_tet_reconnected(const TetMesh& mesh, TetId tet, const Tet& old_vertices) override;
  /// As a removal, and the absorber's vertices (its mass grew).
  void on_tet_absorbed(const TetMesh& mesh, TetId removed, TetId into, TetId moved_from,
                       const Tet& removed_vertices) override;
  /// The vertex and every vertex of its tetrahedra (their rest shapes and edge lengths changed).
  void on_vertex_relocated(const TetMesh& mesh, VertexId vertex,
                           const VertexOrigin& origin) override;
  /// The ends of the last edge, which took the removed one's id.
  void on_edge_removed(const TetMesh& mesh, EdgeId removed, EdgeId moved_from) override;
  void on_material_fraction_changed(const TetMesh& mesh, TetId tet) override;
  void on_mesh_destroyed() override { mesh_ = nullptr; }

 private:
  TetMesh* mesh_;
  std::vector<VertexId> marked_;
  std::vector<std::uint8_t> flags_;  ///< 1 for the vertices in marked_
};

}  // namespace incise
