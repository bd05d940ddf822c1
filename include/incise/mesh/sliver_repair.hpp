#pragma once
// Repair of flat and sliver tetrahedra in an input mesh (`incise convert --fix-slivers`): each
// is removed by collapsing one of its edges. An interior vertex moves onto its neighbour, so
// the boundary stays exactly where it was; a boundary vertex only where it stands off the
// plane of the sliver's opposite face by less than a thousandth of the sliver's longest edge
// (the boundary moves by no more than that, and the largest such move is reported). A
// collapse is made only where every tetrahedron it reshapes stays right side out and no
// thinner than the sliver tolerance.

#include <cstddef>

#include "incise/mesh/tet_mesh.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {

/// What repair_slivers found and did.
struct SliverRepairResult {
  std::size_t flat_before = 0;     ///< zero-volume tetrahedra found
  std::size_t slivers_before = 0;  ///< positive but below the tolerance
  std::size_t collapses = 0;       ///< edges collapsed
  std::size_t flat_after = 0;      ///< zero-volume tetrahedra left
  std::size_t slivers_after = 0;   ///< those no collapse could remove
  double boundary_shift = 0.0;     ///< largest distance the boundary moved (mesh units)
};

/// Removes what it can of `mesh`'s flat tetrahedra and slivers (normalised volume below
/// options.degenerate_tolerance), in place; the mesh's unreferenced vertices are dropped.
SliverRepairResult fix_slivers(TetMesh& mesh, const ValidationOptions& options = {});

}  // namespace incise
