#include "incise/cut/cut_face_marks.hpp"

#include <algorithm>

#include "incise/core/error.hpp"

namespace incise {
namespace {

bool contains(const Tet& tet, VertexId vertex) {
  return std::find(tet.begin(), tet.end(), vertex) != tet.end();
}

}  // namespace

int local_face_of(const Tet& tet, VertexId a, VertexId b, VertexId c) {
  for (int f = 0; f < 4; ++f) {
    if (tet[f] != a && tet[f] != b && tet[f] != c && contains(tet, a) && contains(tet, b) &&
        contains(tet, c)) {
      return f;  // face f is the one opposite local vertex f
    }
  }
  return -1;
}

CutFaceMarks::CutFaceMarks(TetMesh& mesh) : mesh_(&mesh), bits_(mesh.tet_count(), 0) {
  mesh.add_observer(this);
}

CutFaceMarks::~CutFaceMarks() {
  if (mesh_ != nullptr) {
    mesh_->remove_observer(this);
  }
}

void CutFaceMarks::mark(TetId tet, int local_face) {
  set(tet, local_face, true);
}

void CutFaceMarks::unmark(TetId tet, int local_face) {
  set(tet, local_face, false);
}

void CutFaceMarks::set(TetId tet, int local_face, bool on) {
  const auto apply = [on](std::uint8_t& bits, int face) {
    const auto bit = static_cast<std::uint8_t>(1U << face);
    bits = on ? static_cast<std::uint8_t>(bits | bit) : static_cast<std::uint8_t>(bits & ~bit);
  };
  apply(bits_[static_cast<std::size_t>(tet)], local_face);
  const TetId neighbor = mesh_->tet_neighbors(tet)[local_face];
  if (neighbor < 0) {
    return;
  }
  const Tet& v = mesh_->tet(tet);
  const auto& face = tet_local::kFaces[local_face];
  const int across = local_face_of(mesh_->tet(neighbor), v[face[0]], v[face[1]], v[face[2]]);
  INCISE_ASSERT(across >= 0, "face neighbours do not share the face");
  apply(bits_[static_cast<std::size_t>(neighbor)], across);
}

void CutFaceMarks::on_tet_added(const TetMesh& /*mesh*/, TetId tet) {
  INCISE_ASSERT(static_cast<std::size_t>(tet) == bits_.size(), "cut marks out of step");
  bits_.push_back(0);
}

void CutFaceMarks::on_tet_replaced(const TetMesh& mesh, TetId parent,
                                   std::span<const TetId> children, const Tet& parent_vertices) {
  const std::uint8_t parent_bits = bits_[static_cast<std::size_t>(parent)];
  bits_.resize(bits_.size() + children.size() - 1, 0);
  for (TetId child : children) {
    const Tet& c = mesh.tet(child);
    std::uint8_t child_bits = 0;
    // A child of a split is its parent with one corner replaced by the new vertex. Its face f
    // lies inside the parent's face f when it is that face (the replaced corner is f, the
    // opposite one), or when the new vertex lies in that face: all its parents are corners of
    // the face (a point on one of the face's edges, or on the face itself).
    int replaced = -1;
    int differences = 0;
    for (int k = 0; k < 4; ++k) {
      if (c[k] != parent_vertices[k]) {
        replaced = k;
        ++differences;
      }
    }
    if (differences == 1 && parent_bits != 0) {
      const VertexOrigin& origin = mesh.vertex_origin(c[replaced]);
      for (int f = 0; f < 4; ++f) {
        if ((parent_bits >> f & 1U) == 0) {
          continue;
        }
        bool inside = f == replaced;
        if (!inside && origin.kind == VertexOrigin::Kind::kCombination) {
          inside = true;
          for (int p = 0; p < origin.parent_count; ++p) {
            const VertexId q = origin.parents[static_cast<std::size_t>(p)];
            if (q == parent_vertices[f] || !contains(parent_vertices, q)) {
              inside = false;  // off the face: the opposite corner, or not a corner at all
            }
          }
        }
        if (inside) {
          child_bits = static_cast<std::uint8_t>(child_bits | 1U << f);
        }
      }
    } else {
      // Not a split of this kind (no operator makes one today): keep no marks rather than
      // guess; the cutter decides the faces it needs again.
      INCISE_ASSERT(parent_bits == 0 || differences == 1, "unexpected tetrahedron replacement");
    }
    bits_[static_cast<std::size_t>(child)] = child_bits;
  }
}

void CutFaceMarks::on_tet_absorbed(const TetMesh& mesh, TetId removed, TetId into, TetId moved_from,
                                   const Tet& removed_vertices) {
  // The absorber (already reshaped) has grown over the removed tetrahedron: its face toward
  // it now lies where the removed one's face opposite the collapsed vertex was, and takes that
  // face's mark (a face the cut opened there stays one).
  const Tet& grown = mesh.tet(into);
  int collapsed = -1;
  for (int k = 0; k < 4; ++k) {
    if (std::find(grown.begin(), grown.end(), removed_vertices[static_cast<std::size_t>(k)]) ==
        grown.end()) {
      collapsed = k;
    }
  }
  if (collapsed >= 0) {
    const auto& face = tet_local::kFaces[static_cast<std::size_t>(collapsed)];
    const int local = local_face_of(grown, removed_vertices[static_cast<std::size_t>(face[0])],
                                    removed_vertices[static_cast<std::size_t>(face[1])],
                                    removed_vertices[static_cast<std::size_t>(face[2])]);
    if (local >= 0) {
      auto& bits = bits_[static_cast<std::size_t>(into)];
      const auto bit = static_cast<std::uint8_t>(1U << local);
      const bool cut = (bits_[static_cast<std::size_t>(removed)] >> collapsed & 1U) != 0;
      bits = static_cast<std::uint8_t>(cut ? bits | bit : bits & ~bit);
    }
  }
  on_tet_removed(mesh, removed, moved_from, removed_vertices);
}

void CutFaceMarks::on_tet_removed(const TetMesh& /*mesh*/, TetId removed, TetId moved_from,
                                  const Tet& /*removed_vertices*/) {
  bits_[static_cast<std::size_t>(removed)] = bits_[static_cast<std::size_t>(moved_from)];
  bits_.pop_back();
}

}  // namespace incise
