#pragma once
// Which tetrahedron faces lie on the cut: one bit per local face (tet_local::kFaces), kept on
// both tetrahedra that share a marked face while they still do, and on the one left once the
// cut has opened it (then it is a boundary face that the cut made, not the body's exterior).
//
// The marks follow every edit exactly and topologically: when a tetrahedron is split (an
// edge, a face or the tetrahedron itself receives a new vertex), a child's face inherits its
// parent's mark when it lies inside that parent face, which is decided from the new vertex's
// parents (VertexOrigin), never from coordinates. So a face found on the cut stays found,
// however often it is split later, with no geometric look-up and no tolerance.

#include <cstdint>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// Which faces of the mesh lie on the cut, kept through every edit (a mesh observer).
class CutFaceMarks final : public MeshObserver {
 public:
  /// Follows `mesh`, which must outlive it; no face is marked yet.
  explicit CutFaceMarks(TetMesh& mesh);
  CutFaceMarks(const CutFaceMarks&) = delete;
  CutFaceMarks& operator=(const CutFaceMarks&) = delete;
  ~CutFaceMarks() override;

  /// Whether the face opposite local vertex `local_face` of `tet` is on the cut.
  [[nodiscard]] bool is_cut(TetId tet, int local_face) const {
    return (bits_[static_cast<std::size_t>(tet)] >> local_face & 1U) != 0;
  }
  /// Marks a face on the cut, on the tetrahedron across it as well (if any).
  void mark(TetId tet, int local_face);
  /// Takes a mark back, on both sides.
  void unmark(TetId tet, int local_face);
  /// Bit k set: local face k is on the cut.
  [[nodiscard]] std::uint8_t bits(TetId tet) const { return bits_[static_cast<std::size_t>(tet)]; }

  void on_tet_added(const TetMesh& mesh, TetId tet) override;
  void on_tet_replaced(const TetMesh& mesh, TetId parent, std::span<const TetId> children,
                       const Tet& parent_vertices) override;
  void on_tet_removed(const TetMesh& mesh, TetId removed, TetId moved_from,
                      const Tet& removed_vertices) override;
  void on_tet_absorbed(const TetMesh& mesh, TetId removed, TetId into, TetId moved_from,
                       const Tet& removed_vertices) override;
  void on_mesh_destroyed() override { mesh_ = nullptr; }
  void save_state(StateWriter& out) const override {
    out.tag("cut face marks");
    out.values(bits_);
  }
  void load_state(StateReader& in) override {
    in.tag("cut face marks");
    bits_ = in.values<std::uint8_t>("cut face marks");
    if (bits_.size() != mesh_->tet_count()) {
      in.fail("cut face marks", "one per tetrahedron expected");
    }
  }

 private:
  /// Sets or clears a face's bit on both tetrahedra sharing it.
  void set(TetId tet, int local_face, bool on);

  TetMesh* mesh_;
  std::vector<std::uint8_t> bits_;
};

/// The local face of `tet` made of these three vertices (in any order), or -1.
[[nodiscard]] int local_face_of(const Tet& tet, VertexId a, VertexId b, VertexId c);

}  // namespace incise
