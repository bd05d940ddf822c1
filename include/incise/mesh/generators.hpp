#pragma once
// Structured tetrahedral meshes.

#include <array>
#include <random>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// A box of cells, each split into tetrahedra (make_box_grid).
struct BoxGridOptions {
  std::array<int, 3> cells{1, 1, 1};  ///< cells along x, y, z (each >= 1)
  Vec3 size{1.0, 1.0, 1.0};           ///< edge lengths of the box (m), each > 0
  Vec3 origin{0.0, 0.0, 0.0};         ///< minimum corner (m)
  int tets_per_cell = 6;              ///< 6 (Kuhn split along the main diagonal) or 5
};

/// A conforming, positively oriented tetrahedral grid of a box. With 6 tets per cell every
/// cell is split around its (0,0,0)-(1,1,1) diagonal; with 5, cells alternate between the two
/// mirror-image 5-tet splits so that face diagonals match. Throws InputError on bad options.
[[nodiscard]] TetMesh make_box_grid(const BoxGridOptions& options);

/// The mesh with every vertex off its boundary moved at random, along each axis by up to
/// `fraction` of its shortest edge: an irregular mesh with the same boundary and volume. A
/// move that would leave a tetrahedron with less than a fifth of its volume is not made.
[[nodiscard]] TetMesh perturb_interior(const TetMesh& mesh, double fraction, std::mt19937& rng);

}  // namespace incise
