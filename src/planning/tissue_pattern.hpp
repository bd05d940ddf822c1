#pragma once
// The point pairs a layered tissue's second derivatives couple, and the continuum's
// tetrahedra added to a PointBlockMatrix over them: shared by Newton's prediction and the
// continuum's equilibrium initialisation.

#include <algorithm>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "incise/core/parallel_for.hpp"
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

/// Runs add(low, high) for disjoint ranges of the matrix's columns that cover them all (whole
/// points' columns), side by side on worker threads: an assembly whose add() adds, in element
/// order, only the blocks whose columns lie in [low, high) gives the same sums as one thread.
void for_column_ranges(const PointBlockMatrix& matrix, const std::function<void(int, int)>& add);
/// Fewer points than this to a range are not worth another thread's walk over the elements.
inline constexpr int kLeastPointsPerRange = 2048;

/// Prisms per block of per-prism terms held at once (a few MB at most).
inline constexpr std::size_t kPrismBlock = 4096;

/// For blocks of kPrismBlock prisms: compute(p, k) for each prism p of the block (k its place
/// in the block) on worker threads, then take(first, last) for the block once they are all
/// computed. A take() that adds the block's terms in prism order gives the same sums, to the
/// bit, on any thread count.
template <typename Compute, typename Take>
void for_prism_blocks(std::size_t prisms, std::size_t grain, const Compute& compute,
                      const Take& take) {
  for (std::size_t first = 0; first < prisms; first += kPrismBlock) {
    const std::size_t last = std::min(first + kPrismBlock, prisms);
    parallel_for(first, last, grain, [&](std::size_t begin, std::size_t end) {
      for (std::size_t p = begin; p < end; ++p) {
        compute(p, p - first);
      }
    });
    take(first, last);
  }
}

/// Which of a prism's second derivatives add_prism_hessians adds.
struct PrismTerms {
  bool tets = false;    ///< the continuum's three tetrahedra (stable_neo_hookean.hpp)
  bool volume = false;  ///< the volume term (where the tissue's volume_weight > 0)
  /// Each term's positive semi-definite form instead of the true second derivative.
  bool convex = false;
};

/// Where each prism's 21 blocks (PrismBlocks' order) go in a matrix over `pattern`: looked up
/// once, for every assembly of that matrix.
[[nodiscard]] std::vector<PointBlockMatrix::Target> prism_targets(const LayeredTissue& tissue,
                                                                  const CouplingPattern& pattern,
                                                                  const PointBlockMatrix& matrix);

/// Adds the prisms' second derivatives at positions x (m), per prism one 18 x 18 matrix of the
/// chosen terms, added in prism order (the same sum for any thread count); `targets` from
/// prism_targets() for this matrix.
void add_prism_hessians(const LayeredTissue& tissue,
                        std::span<const PointBlockMatrix::Target> targets, std::span<const Vec3> x,
                        const PrismTerms& terms, PointBlockMatrix& matrix);

}  // namespace incise::planning
