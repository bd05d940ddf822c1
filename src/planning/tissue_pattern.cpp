#include "tissue_pattern.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdint>
#include <functional>

#include "incise/core/parallel_for.hpp"
#include "incise/mesh/edge_index.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/physics/stable_neo_hookean.hpp"
#include "incise/planning/prism.hpp"

namespace incise::planning {

CouplingPattern coupling_pattern(const LayeredTissue& tissue) {
  CouplingPattern pattern;
  // The mesh's flat edge table (one cache miss a lookup), not std::unordered_map's chained
  // nodes: at 59k points (360k pairs, 15 lookups a prism) 93 -> 30-34 ms, twice per plan.
  EdgeIndex index;
  index.reserve(tissue.springs.size() + tissue.prisms.size() * 4);
  for (const Spring& spring : tissue.springs) {
    index.try_emplace(edge_key(spring.a, spring.b), static_cast<EdgeId>(pattern.pairs.size()));
    pattern.pairs.emplace_back(spring.a, spring.b);
  }
  pattern.prism_pairs.reserve(tissue.prisms.size() * 15);
  for (const Prism& prism : tissue.prisms) {
    for (std::size_t i = 0; i < 6; ++i) {
      for (std::size_t j = i + 1; j < 6; ++j) {
        const int a = prism.points[i];
        const int b = prism.points[j];
        const auto [pair, added] =
            index.try_emplace(edge_key(a, b), static_cast<EdgeId>(pattern.pairs.size()));
        if (added) {
          pattern.pairs.emplace_back(a, b);
        }
        pattern.prism_pairs.push_back(static_cast<std::size_t>(pair));
      }
    }
  }
  return pattern;
}

void for_column_ranges(const PointBlockMatrix& matrix, const std::function<void(int, int)>& add) {
  // One range per worker: each range walks every element and adds only its own blocks, so
  // more ranges than workers would only repeat the walk.
  const int points = matrix.rows() / 3;
  const int ranges =
      std::clamp(points / kLeastPointsPerRange, 1, tbb::this_task_arena::max_concurrency());
  parallel_for(0, static_cast<std::size_t>(ranges), 1, [&](std::size_t first, std::size_t last) {
    const auto bound = [&](std::size_t r) {
      return 3 * static_cast<int>(static_cast<std::int64_t>(points) * static_cast<std::int64_t>(r) /
                                  ranges);
    };
    for (std::size_t range = first; range < last; ++range) {
      add(bound(range), bound(range + 1));
    }
  });
}

void add_prism_hessians(const LayeredTissue& tissue, const CouplingPattern& pattern,
                        std::span<const Vec3> x, const PrismTerms& terms,
                        PointBlockMatrix& matrix) {
  const bool volume = terms.volume && tissue.volume_weight > 0.0;
  if (!terms.tets && !volume) {
    return;
  }
  // A prism's matrix (its three tetrahedra's and its volume term's, over its six corners) for a
  // block of prisms in parallel (the eigen-decompositions are most of the work), then added
  // into the matrix in prism order, 21 blocks each: the sum is the same for any thread count.
  std::vector<PrismHessian> element(std::min(kPrismBlock, tissue.prisms.size()));  // 2.6 kB each
  std::vector<char> empty(element.size());
  for_prism_blocks(
      tissue.prisms.size(), 64,
      [&](std::size_t p, std::size_t slot) {
        const Prism& prism = tissue.prisms[p];
        PrismHessian& h = element[slot];
        h.setZero();
        bool any = false;
        for (std::size_t t = 0; t < 3 && terms.tets; ++t) {
          const PrismTet& tet = prism.tets[t];
          if (tet.rest.volume == 0.0) {
            continue;
          }
          any = true;
          const ElementMatrix k = neo_hookean_stiffness(tet_corners(prism, tet, x), tet.rest,
                                                        prism.material, terms.convex);
          for (std::size_t a = 0; a < 4; ++a) {
            const auto ia = static_cast<Eigen::Index>(3 * tet.corners[a]);
            for (std::size_t b = 0; b < 4; ++b) {
              const auto ib = static_cast<Eigen::Index>(3 * tet.corners[b]);
              h.block<3, 3>(ia, ib) +=
                  k.block<3, 3>(static_cast<Eigen::Index>(3 * a), static_cast<Eigen::Index>(3 * b));
            }
          }
        }
        if (volume && prism.rest_volume != 0.0) {
          any = true;
          PrismPoints corners;
          for (std::size_t i = 0; i < 6; ++i) {
            corners[i] = x[static_cast<std::size_t>(prism.points[i])];
          }
          const std::array<Vec3, 6> dv = prism_volume_gradient(corners);
          const double weight = tissue.volume_weight / std::abs(prism.rest_volume);
          // kappa / |V0| ((grad V)(grad V)^T + (V - V0) grad^2 V); the convex form keeps
          // the first.
          for (std::size_t i = 0; i < 6; ++i) {
            for (std::size_t j = 0; j < 6; ++j) {
              h.block<3, 3>(static_cast<Eigen::Index>(3 * i), static_cast<Eigen::Index>(3 * j)) +=
                  weight * dv[i] * dv[j].transpose();
            }
          }
          if (!terms.convex) {
            h += (weight * (prism_volume(corners) - prism.rest_volume)) *
                 prism_volume_hessian(corners);
          }
        }
        empty[slot] = any ? 0 : 1;
      },
      [&](std::size_t first, std::size_t last) {
        // Added by column ranges side by side, each range's blocks in prism order: every value
        // gets its terms in the same order as one thread would add them.
        for_column_ranges(matrix, [&](int low, int high) {
          const auto mine = [low, high](int column) { return column >= low && column < high; };
          for (std::size_t p = first; p < last; ++p) {
            if (empty[p - first] != 0) {
              continue;
            }
            const Prism& prism = tissue.prisms[p];
            const PrismHessian& h = element[p - first];
            for (std::size_t i = 0, k = 0; i < 6; ++i) {
              const auto bi = static_cast<Eigen::Index>(3 * i);
              if (mine(matrix.row(prism.points[i]))) {
                matrix.add_diagonal(prism.points[i], h.block<3, 3>(bi, bi));
              }
              for (std::size_t j = i + 1; j < 6; ++j, ++k) {
                const std::size_t pair = pattern.prism_pairs[p * 15 + k];
                if (!mine(matrix.coupling_column(pair))) {
                  continue;
                }
                const auto bj = static_cast<Eigen::Index>(3 * j);
                // The block at (first, second) of the pair as stored.
                const bool same_order = pattern.pairs[pair].first == prism.points[i];
                matrix.add_coupling(
                    pair, same_order ? Mat3(h.block<3, 3>(bi, bj)) : Mat3(h.block<3, 3>(bj, bi)));
              }
            }
          }
        });
      });
}

}  // namespace incise::planning
