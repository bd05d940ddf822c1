#pragma once
// Conforming refinement operators built on the TetMesh edit operations: each inserts one vertex
// and replaces every tetrahedron that touches the split entity, so no hanging node is left.
// (The generic forms of the seed's splitEdge / splitFace operators.)

#include <array>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// Splits every tetrahedron around `edge` = (a, b) at (1 - t) a + t b, 0 < t < 1.
/// Returns the new vertex.
VertexId split_edge(TetMesh& mesh, EdgeId edge, double t);

/// Splits the one or two tetrahedra sharing face `local_face` of `tet` into three each, at the
/// point with barycentric `weights` (positive, summing to 1) of the face's vertices (in
/// tet_local::kFaces order). Returns the new vertex.
VertexId split_face(TetMesh& mesh, TetId tet, int local_face, const std::array<double, 3>& weights);

/// Splits a tetrahedron into four at the interior point with barycentric `weights`.
VertexId split_tet(TetMesh& mesh, TetId tet, const std::array<double, 4>& weights);

}  // namespace incise
