#pragma once
// A uniform grid of tetrahedron bounding boxes that follows every mesh edit, so finding the
// tetrahedra near the blade costs the same on any mesh size. The boxes are those of the rest
// positions, or of current positions (a VertexData that follows the mesh) when the cut happens
// in the deformed configuration; after those move, refit() rebuilds the grid.

#include <vector>

#include "incise/core/stamped_set.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// A uniform grid of cells listing the tetrahedra whose bounding boxes reach into each, kept
/// through every edit (a mesh observer): the cutters' spatial index.
class TetGrid final : public MeshObserver {
 public:
  /// Cell size defaults to the mean edge length. `positions` (m), when given, must
  /// outlive the grid.
  explicit TetGrid(TetMesh& mesh, const VertexData<Vec3>* positions = nullptr,
                   double cell_size = 0.0);
  ~TetGrid() override;
  TetGrid(const TetGrid&) = delete;
  TetGrid& operator=(const TetGrid&) = delete;

  /// Tetrahedra whose bounding box overlaps [low, high] (each once, unsorted).
  void query(const Vec3& low, const Vec3& high, std::vector<TetId>& out) const;
  [[nodiscard]] double cell_size() const { return cell_; }  ///< m
  /// Re-inserts every tetrahedron at its current bounds (after the positions moved).
  void refit();
  /// The position the grid uses for a vertex (m).
  [[nodiscard]] const Vec3& position(VertexId vertex) const {
    return positions_ != nullptr ? (*positions_)[vertex] : mesh_->rest_position(vertex);
  }

  void on_tet_added(const TetMesh& mesh, TetId tet) override;
  void on_tet_replaced(const TetMesh& mesh, TetId parent, std::span<const TetId> children,
                       const Tet& parent_vertices) override;
  void on_tet_removed(const TetMesh& mesh, TetId removed, TetId moved_from,
                      const Tet& removed_vertices) override;
  void on_vertex_relocating(const TetMesh& mesh, VertexId vertex) override;
  void on_tet_reshaped(const TetMesh& mesh, TetId tet, const Tet& old_vertices) override;
  void on_mesh_destroyed() override { mesh_ = nullptr; }
  /// The cells exactly as filed: queries list tetrahedra in filing order.
  void save_state(StateWriter& out) const override;
  void load_state(StateReader& in) override;

 private:
  void cell_range(const Vec3& low, const Vec3& high, std::array<long, 3>& first,
                  std::array<long, 3>& last) const;
  void bounds(const Tet& tet, Vec3& low, Vec3& high) const;
  /// Calls visit(cell index) for every cell overlapping [low, high].
  template <typename Visit>
  void for_each_cell_in_box(const Vec3& low, const Vec3& high, Visit visit) const;
  /// Calls visit(cell) for every cell the tetrahedron's bounding box overlaps.
  template <typename Visit>
  void for_each_cell(const Tet& vertices, Visit visit) const;
  void insert(TetId tet, const Tet& vertices) const;
  void erase(TetId tet, const Tet& vertices);
  void rename(TetId from, TetId to, const Tet& vertices);
  /// Takes a tetrahedron off the list waiting to be filed; false when it was not on it.
  bool unpend(TetId tet);
  std::size_t cell_index(long i, long j, long k) const;
  /// Files the tetrahedra taken out while a vertex moved, at their new bounds. Done lazily (at
  /// the next query or edit), when every observer, current positions included, has followed.
  void file_pending() const;

  TetMesh* mesh_;
  const VertexData<Vec3>* positions_;
  Vec3 origin_;
  double cell_ = 1.0;
  std::array<long, 3> dims_{1, 1, 1};
  mutable std::vector<std::vector<TetId>> cells_;
  mutable std::vector<TetId> pending_;  ///< around a relocated vertex, not filed yet
  mutable StampedSet seen_;             ///< a query's tetrahedra so far
};

}  // namespace incise
