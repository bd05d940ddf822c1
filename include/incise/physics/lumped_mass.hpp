#pragma once
// Lumped masses that survive cuts.

#include "incise/mesh/attributes.hpp"

namespace incise {

/// A hook for a per-tetrahedron mass container (kg) that shares a replaced tetrahedron's mass
/// among its children in proportion to their rest volumes, so an edit conserves the total
/// exactly whatever rounding the new vertices carry. Children with the same rest corners
/// (XFEM's virtual elements, weighted by their material fractions) each keep the whole mass. `mesh`
/// is the owner's mesh pointer, read when the hook runs (it follows relocations).
[[nodiscard]] TetData<double>::Hook mass_split_by_volume(TetMesh* const& mesh);

}  // namespace incise
