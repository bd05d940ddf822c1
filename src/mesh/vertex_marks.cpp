#include "incise/mesh/vertex_marks.hpp"

#include <algorithm>

namespace incise {

VertexMarks::VertexMarks(TetMesh& mesh) : mesh_(&mesh) {
  mesh.add_observer(this);
}

VertexMarks::~VertexMarks() {
  if (mesh_ != nullptr) {
    mesh_->remove_observer(this);
  }
}

void VertexMarks::mark(VertexId vertex) {
  const auto v = static_cast<std::size_t>(vertex);
  if (v >= flags_.size()) {
    flags_.resize(std::max(v + 1, mesh_ != nullptr ? mesh_->vertex_count() : 0), 0);
  }
  if (flags_[v] == 0) {
    flags_[v] = 1;
    marked_.push_back(vertex);
  }
}

void VertexMarks::mark(const Tet& tet) {
  for (VertexId v : tet) {
    mark(v);
  }
}

void VertexMarks::mark_all() {
  for (std::size_t v = 0; v < mesh_->vertex_count(); ++v) {
    mark(static_cast<VertexId>(v));
  }
}

void VertexMarks::clear() {
  for (VertexId v : marked_) {
    flags_[static_cast<std::size_t>(v)] = 0;
  }
  marked_.clear();
}

void VertexMarks::on_vertex_added(const TetMesh&, VertexId vertex, const VertexOrigin&) {
  mark(vertex);
}

void VertexMarks::on_tet_added(const TetMesh& mesh, TetId tet) {
  mark(mesh.tet(tet));
}

void VertexMarks::on_tet_replaced(const TetMesh& mesh, TetId, std::span<const TetId> children,
                                  const Tet& parent_vertices) {
  mark(parent_vertices);
  for (TetId child : children) {
    mark(mesh.tet(child));
  }
}

void VertexMarks::on_tet_removed(const TetMesh& mesh, TetId removed, TetId moved_from,
                                 const Tet& removed_vertices) {
  mark(removed_vertices);
  if (removed != moved_from) {
    mark(mesh.tet(removed));  // lists that name tetrahedra by id name it by its old one
  }
}

void VertexMarks::on_tet_reconnected(const TetMesh& mesh, TetId tet, const Tet& old_vertices) {
  mark(old_vertices);
  mark(mesh.tet(tet));
}

void VertexMarks::on_tet_absorbed(const TetMesh& mesh, TetId removed, TetId into, TetId moved_from,
                                  const Tet& removed_vertices) {
  on_tet_removed(mesh, removed, moved_from, removed_vertices);
  mark(mesh.tet(into == moved_from ? removed : into));  // the absorber, wherever it lives now
}

void VertexMarks::on_vertex_relocated(const TetMesh& mesh, VertexId vertex, const VertexOrigin&) {
  mark(vertex);
  for (TetId t : mesh.vertex_tets(vertex)) {
    mark(mesh.tet(t));
  }
}

void VertexMarks::on_edge_removed(const TetMesh& mesh, EdgeId removed, EdgeId moved_from) {
  if (removed != moved_from) {
    mark(mesh.edge(removed)[0]);
    mark(mesh.edge(removed)[1]);
  }
}

void VertexMarks::on_material_fraction_changed(const TetMesh& mesh, TetId tet) {
  mark(mesh.tet(tet));
}

}  // namespace incise
