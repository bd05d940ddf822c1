#pragma once
// Opening a cut, for any cutter: the tetrahedra around a vertex fall into groups joined through
// faces that are not cut, and each group but one gets its own copy of the vertex. The cutter
// says which faces are cut through a predicate (the subdivision cutter: its remembered marks;
// an XFEM cutter: its own rule), so the rule for opening is written once.

#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// Whether face `local_face` (opposite corner `local_face`) of `tet` is a cut face.
using CutFacePredicate = std::function<bool(TetId tet, int local_face)>;

/// Separates the tetrahedra around `vertex` at cut faces: the group holding the smallest
/// tetrahedron id keeps the vertex, every other group gets a copy (TetMesh::duplicate_vertex,
/// so attributes follow). Returns the copies made, none when one group holds them all.
std::vector<VertexId> separate_at_cut_faces(TetMesh& mesh, VertexId vertex,
                                            const CutFacePredicate& is_cut);

/// Edges left pinched after separation: (v, w), v < w, with v from `vertices`, where more than
/// two boundary faces around v meet w (two wedges touching along the edge) and v or w lies on
/// the cut. Splitting such an edge puts a vertex inside the cut that can be separated.
[[nodiscard]] std::vector<std::pair<VertexId, VertexId>> pinched_edges(
    const TetMesh& mesh, std::span<const VertexId> vertices,
    const std::function<bool(VertexId)>& on_cut);

}  // namespace incise
