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

/// An absorb hook for the same container: a tetrahedron a collapse removes gives its mass to
/// the one that grows over its space, so the total is kept (both have material fraction 1:
/// the subdivision cutter's meshes).
[[nodiscard]] TetData<double>::AbsorbHook mass_absorbed();

/// A vertex's lumped mass (kg): a quarter of each of its tetrahedra's mass times its material
/// fraction, summed in the mesh's order (so the same whether a model was built afresh or
/// followed edits).
[[nodiscard]] double vertex_lumped_mass(const TetMesh& mesh, const TetData<double>& tet_mass,
                                        VertexId vertex);

/// Sets both hooks on a per-tetrahedron mass container.
void conserve_mass(TetData<double>& mass, TetMesh* const& mesh);

}  // namespace incise
