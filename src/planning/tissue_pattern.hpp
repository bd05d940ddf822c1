#pragma once
// The point pairs a layered tissue's second derivatives couple, and the continuum's
// tetrahedra added to a PointBlockMatrix over them: shared by Newton's prediction and the
// continuum's equilibrium initialisation.

#include <span>
#include <utility>
#include <vector>

#include "incise/planning/layered_tissue.hpp"
#include "point_block_matrix.hpp"

namespace incise::planning {

/// Every spring (pair s = spring s), then the prisms' corner pairs that no spring joins. Per
/// prism, the pair of each of its 15 corner pairs (i, j), i < j, in row order.
struct CouplingPattern {
  std::vector<std::pair<int, int>> pairs;
  std::vector<std::size_t> prism_pairs;
};

[[nodiscard]] CouplingPattern coupling_pattern(const LayeredTissue& tissue);

/// Adds the continuum's tetrahedra's stiffness at positions x: the true Hessian, or with
/// `convex` its positive semi-definite form (stable_neo_hookean.hpp).
void add_tet_stiffness(const LayeredTissue& tissue, const CouplingPattern& pattern,
                       std::span<const Vec3> x, bool convex, PointBlockMatrix& matrix);

}  // namespace incise::planning
