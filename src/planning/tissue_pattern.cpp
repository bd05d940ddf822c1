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

std::vector<PointBlockMatrix::Target> prism_targets(const LayeredTissue& tissue,
                                                    const CouplingPattern& pattern,
                                                    const PointBlockMatrix& matrix) {
  std::vector<PointBlockMatrix::Target> targets(tissue.prisms.size() * 21);
  for (std::size_t p = 0; p < tissue.prisms.size(); ++p) {
    const Prism& prism = tissue.prisms[p];
    const std::span<PointBlockMatrix::Target> mine(targets.data() + p * 21, 21);
    for (std::size_t i = 0, k = 0; i < 6; ++i) {
      mine[prism_block(i, i)] = matrix.diagonal_target(prism.points[i]);
      for (std::size_t j = i + 1; j < 6; ++j, ++k) {
        const std::size_t pair = pattern.prism_pairs[p * 15 + k];
        // The prism's block (i, j) is the pair's (first, second) when its first is point i.
        mine[prism_block(i, j)] =
            matrix.coupling_target(pair, pattern.pairs[pair].first == prism.points[i]);
      }
    }
  }
  return targets;
}

void add_prism_hessians(const LayeredTissue& tissue,
                        std::span<const PointBlockMatrix::Target> targets, std::span<const Vec3> x,
                        const PrismTerms& terms, PointBlockMatrix& matrix) {
  const bool volume = terms.volume && tissue.volume_weight > 0.0;
  if (!terms.tets && !volume) {
    return;
  }
  // A prism's matrix (its three tetrahedra's and its volume term's, over its six corners, as
  // its 21 blocks on and above the diagonal) for a block of prisms in parallel, then added into
  // the matrix in prism order: the sum is the same for any thread count.
  std::vector<PrismBlocks> element(std::min(kPrismBlock, tissue.prisms.size()));  // 1.5 kB each
  std::vector<char> empty(element.size());
  for_prism_blocks(
      tissue.prisms.size(), 64,
      [&](std::size_t p, std::size_t slot) {
        const Prism& prism = tissue.prisms[p];
        PrismBlocks& h = element[slot];
        for (Mat3& block : h) {
          block.setZero();
        }
        bool any = false;
        for (std::size_t t = 0; t < 3 && terms.tets; ++t) {
          const PrismTet& tet = prism.tets[t];
          if (tet.rest.volume == 0.0) {
            continue;
          }
          any = true;
          const ElementStiffnessBlocks k = neo_hookean_stiffness_blocks(
              tet_corners(prism, tet, x), tet.rest, prism.material, terms.convex);
          for (std::size_t a = 0, next = 0; a < 4; ++a) {
            const auto ia = static_cast<std::size_t>(tet.corners[a]);
            for (std::size_t b = a; b < 4; ++b, ++next) {
              const auto ib = static_cast<std::size_t>(tet.corners[b]);
              if (ia <= ib) {
                h[prism_block(ia, ib)] += k[next];
              } else {
                h[prism_block(ib, ia)] += k[next].transpose();
              }
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
            const Vec3 weighted = weight * dv[i];
            for (std::size_t j = i; j < 6; ++j) {
              h[prism_block(i, j)].noalias() += weighted * dv[j].transpose();
            }
          }
          if (!terms.convex) {
            add_prism_volume_hessian(corners, weight * (prism_volume(corners) - prism.rest_volume),
                                     h);
          }
        }
        empty[slot] = any ? 0 : 1;
      },
      [&](std::size_t first, std::size_t last) {
        // Added by column ranges side by side, each range's blocks in prism order: every value
        // gets its terms in the same order as one thread would add them.
        for_column_ranges(matrix, [&](int low, int high) {
          const int from = matrix.value_start(low);
          const int to = matrix.value_start(high);
          for (std::size_t p = first; p < last; ++p) {
            if (empty[p - first] != 0) {
              continue;
            }
            const PrismBlocks& h = element[p - first];
            const PointBlockMatrix::Target* target = targets.data() + p * 21;
            for (std::size_t i = 0, k = 0; i < 6; ++i) {
              for (std::size_t j = i; j < 6; ++j, ++k) {
                if (target[k].first < from || target[k].first >= to) {
                  continue;  // another range's, or not in the system
                }
                if (i == j) {
                  matrix.add_diagonal(target[k], h[k]);
                } else {
                  matrix.add_coupling(target[k], h[k]);
                }
              }
            }
          }
        });
      });
}

}  // namespace incise::planning
