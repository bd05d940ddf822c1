#pragma once
// The materials of a body: a table, and the material of each tetrahedron, which follows every
// edit of the mesh (children of a split keep their parent's material; a tetrahedron added
// afresh gets material 0). Models keep one and look materials up per element.

#include <span>
#include <vector>

#include "incise/mesh/attributes.hpp"
#include "incise/physics/material.hpp"

namespace incise {

/// A material table and one index into it per tetrahedron (empty: all 0). Plain data, for
/// building models.
struct MaterialAssignment {
  std::vector<Material> table;  ///< the materials
  std::vector<int> ids;         ///< per tetrahedron, an index into `table`
  /// Every tetrahedron of one material.
  static MaterialAssignment uniform(const Material& material) { return {{material}, {}}; }
};

/// The material of every tetrahedron, kept through the mesh's edits (a child keeps its
/// parent's).
class MaterialMap {
 public:
  /// Throws InputError for an empty table, an invalid material (naming its index), ids of the
  /// wrong count or out of the table's range (naming the tetrahedron).
  MaterialMap(TetMesh& mesh, const MaterialAssignment& assignment);

  /// A tetrahedron's material.
  [[nodiscard]] const Material& of(TetId tet) const { return table_[ids_[tet]]; }
  /// A tetrahedron's index into the table.
  [[nodiscard]] int id(TetId tet) const { return ids_[tet]; }
  /// The materials.
  [[nodiscard]] std::span<const Material> table() const { return table_; }

 private:
  std::vector<Material> table_;
  TetData<int> ids_;
};

}  // namespace incise
