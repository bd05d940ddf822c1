#include "tissue_pattern.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <unordered_map>

#include "incise/mesh/tet_mesh.hpp"

namespace incise::planning {

namespace {

/// The index among a prism's 15 corner pairs (i, j), i < j, in coupling_pattern's order.
constexpr std::size_t prism_pair_index(std::size_t i, std::size_t j) {
  return i * 6 - i * (i + 1) / 2 + (j - i - 1);
}

}  // namespace

CouplingPattern coupling_pattern(const LayeredTissue& tissue) {
  CouplingPattern pattern;
  std::unordered_map<std::uint64_t, std::size_t> index;
  index.reserve(tissue.springs.size() * 2 + tissue.prisms.size() * 8);
  for (const Spring& spring : tissue.springs) {
    index.emplace(edge_key(spring.a, spring.b), pattern.pairs.size());
    pattern.pairs.emplace_back(spring.a, spring.b);
  }
  pattern.prism_pairs.reserve(tissue.prisms.size() * 15);
  for (const Prism& prism : tissue.prisms) {
    for (std::size_t i = 0; i < 6; ++i) {
      for (std::size_t j = i + 1; j < 6; ++j) {
        const int a = prism.points[i];
        const int b = prism.points[j];
        const auto [it, added] = index.emplace(edge_key(a, b), pattern.pairs.size());
        if (added) {
          pattern.pairs.emplace_back(a, b);
        }
        pattern.prism_pairs.push_back(it->second);
      }
    }
  }
  return pattern;
}

void add_tet_stiffness(const LayeredTissue& tissue, const CouplingPattern& pattern,
                       std::span<const Vec3> x, bool convex, PointBlockMatrix& matrix) {
  // Element matrices for a block of prisms in parallel (the eigen-decompositions are most of
  // the work), then added into the matrix in order: the sum is the same for any thread count.
  constexpr std::size_t kBlock = 2048;  // prisms: 2048 x 3 x 1.1 kB of matrices
  std::vector<ElementMatrix> element(3 * kBlock);
  for (std::size_t first = 0; first < tissue.prisms.size(); first += kBlock) {
    const std::size_t last = std::min(first + kBlock, tissue.prisms.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(first, last, 64),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t p = range.begin(); p < range.end(); ++p) {
                          const Prism& prism = tissue.prisms[p];
                          for (std::size_t t = 0; t < 3; ++t) {
                            const PrismTet& tet = prism.tets[t];
                            if (tet.rest.volume != 0.0) {
                              element[3 * (p - first) + t] = neo_hookean_stiffness(
                                  tet_corners(prism, tet, x), tet.rest, prism.material, convex);
                            }
                          }
                        }
                      });
    for (std::size_t p = first; p < last; ++p) {
      const Prism& prism = tissue.prisms[p];
      for (std::size_t t = 0; t < 3; ++t) {
        const PrismTet& tet = prism.tets[t];
        if (tet.rest.volume == 0.0) {
          continue;
        }
        const ElementMatrix& k = element[3 * (p - first) + t];
        for (std::size_t a = 0; a < 4; ++a) {
          const auto ba = static_cast<Eigen::Index>(3 * a);
          const std::size_t ia = tet.corners[a];
          matrix.add_diagonal(prism.points[ia], k.block<3, 3>(ba, ba));
          for (std::size_t b = a + 1; b < 4; ++b) {
            const auto bb = static_cast<Eigen::Index>(3 * b);
            const std::size_t ib = tet.corners[b];
            const std::size_t pair =
                pattern.prism_pairs[p * 15 + prism_pair_index(std::min(ia, ib), std::max(ia, ib))];
            // The block at (first, second) of the pair as stored.
            const bool same_order = pattern.pairs[pair].first == prism.points[ia];
            matrix.add_coupling(
                pair, same_order ? Mat3(k.block<3, 3>(ba, bb)) : Mat3(k.block<3, 3>(bb, ba)));
          }
        }
      }
    }
  }
}

}  // namespace incise::planning
