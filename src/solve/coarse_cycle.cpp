#include "coarse_cycle.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <random>
#include <tuple>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/solve/direct_factorization.hpp"

namespace incise::coarse {

namespace {

/// Per task in the cycle's passes: nodes (an aggregate is some 1,500 vertices), or groups.
constexpr std::size_t kNodeGrain = 64;
constexpr std::size_t kGroupGrain = 4;
/// The damped smoother's largest eigenvalue on a level's matrix at most (below 2, where the
/// cycle would stop being positive definite). Undamped it is 1.9 on the peers' box at 48k and
/// 384k tets: too close; damping to 1.6 cost 4-8 % more iterations than none there.
constexpr double kSmootherReach = 1.6;

/// Each node with its first ungrouped neighbours (in column order), kGroupLimit in all at
/// most: the prototype's rule (BENCHMARKS.md, session 53). Returns each node's group and the
/// count.
std::pair<std::vector<int>, int> limited_groups(std::span<const std::size_t> slot_first,
                                                std::span<const int> slot_column,
                                                std::size_t nodes) {
  std::vector<int> group(nodes, -1);
  int count = 0;
  for (std::size_t a = 0; a < nodes; ++a) {
    if (group[a] >= 0) {
      continue;
    }
    group[a] = count;
    std::size_t taken = 1;
    for (std::size_t s = slot_first[a]; s != slot_first[a + 1] && taken < CoarseCycle::kGroupLimit;
         ++s) {
      const auto b = static_cast<std::size_t>(slot_column[s]);
      if (group[b] < 0) {
        group[b] = count;
        ++taken;
      }
    }
    ++count;
  }
  return {std::move(group), count};
}

/// A level's nodes' graph: each node tied to the others its row couples it to (weight 1).
Graph level_graph(std::span<const std::size_t> slot_first, std::span<const int> slot_column,
                  std::size_t nodes) {
  Graph graph;
  for (std::size_t a = 0; a < nodes; ++a) {
    for (std::size_t s = slot_first[a]; s != slot_first[a + 1]; ++s) {
      if (slot_column[s] != static_cast<int>(a)) {
        graph.node.push_back(slot_column[s]);
        graph.weight.push_back(1.0);
      }
    }
    graph.first.push_back(graph.node.size());
  }
  return graph;
}

/// A level's slot pattern from each row's sorted columns.
void set_pattern(std::span<const int> slot_row, std::span<const int> slot_column, std::size_t nodes,
                 std::vector<int>& rows, std::vector<int>& columns, std::vector<std::size_t>& first,
                 std::vector<int>& diagonal) {
  rows.assign(slot_row.begin(), slot_row.end());
  columns.assign(slot_column.begin(), slot_column.end());
  key_offsets(rows, nodes, first);
  diagonal.assign(nodes, -1);
  for (std::size_t a = 0; a < nodes; ++a) {
    const auto row_begin = columns.begin() + static_cast<std::ptrdiff_t>(first[a]);
    const auto row_end = columns.begin() + static_cast<std::ptrdiff_t>(first[a + 1]);
    const auto found = std::lower_bound(row_begin, row_end, static_cast<int>(a));
    INCISE_ASSERT(found != row_end && *found == static_cast<int>(a),
                  "a coarse node couples to itself");
    diagonal[a] = static_cast<int>(found - columns.begin());
  }
}

}  // namespace

CoarseCycle::CoarseCycle() : factor_(std::make_unique<DirectFactorization>()) {}

CoarseCycle::~CoarseCycle() = default;

std::vector<std::size_t> CoarseCycle::level_sizes() const {
  std::vector<std::size_t> sizes;
  for (const Level& level : levels_) {
    sizes.push_back(level.size());
  }
  return sizes;
}

void CoarseCycle::build(std::size_t nodes, std::span<const int> slot_row,
                        std::span<const int> slot_column, std::size_t exact_limit) {
  levels_.resize(1);  // the aggregates' level keeps its pages
  Level& base = levels_.front();
  set_pattern(slot_row, slot_column, nodes, base.slot_row, base.slot_column, base.slot_first,
              base.diagonal_slot);
  // Written whole by the caller before assemble(); room kept for the cuts to come (growth.hpp).
  resize_for_edits(base.blocks, slot_row.size());
  while (kModes * levels_.back().size() > exact_limit && levels_.back().size() > 1) {
    const std::size_t below = levels_.size() - 1;
    const Level& level = levels_[below];
    auto [group, count] = limited_groups(level.slot_first, level.slot_column, level.size());
    if (static_cast<std::size_t>(count) == level.size()) {
      break;  // nothing coupled left to group
    }
    if (below == 0 && kModes * static_cast<std::size_t>(count) <= exact_limit) {
      // One level of groups, factorised: grouped without a limit (about a ring each) its solve
      // is cheaper. Limited there, the 50k-tet body's iterations fell 3.5 % and its coarse
      // solve cost 15 % more (BENCHMARKS.md, session 54). Above groups of groups the top is
      // small either way, and limited it saved 3 % of the 384k-tet box's iterations.
      std::tie(group, count) =
          greedy_aggregates(level_graph(level.slot_first, level.slot_column, level.size()),
                            std::vector<char>(level.size(), 1));
    }
    add_group_level(below, std::move(group), static_cast<std::size_t>(count));
  }
  Level& top = levels_.back();
  top.group_of.clear();
  top.group_first.clear();
  top.group_member.clear();
  top.group_slot.clear();
  top.group_map.clear();
  top.own_inverse.clear();
  top.mirror_slot.clear();
  top.coupling_of_slot.clear();
  build_exact();
}

void CoarseCycle::add_group_level(std::size_t below, std::vector<int> group_of,
                                  std::size_t groups) {
  Level above;
  {
    Level& low = levels_[below];
    low.group_of = std::move(group_of);
    group_by_key(low.group_of, groups, low.group_first, low.group_member);
    // Group g couples h where a slot (a, b) has a in g and b in h; numbered row by row with
    // sorted columns, as the level below.
    std::vector<std::vector<int>> columns(groups);
    for (std::size_t s = 0; s < low.slot_row.size(); ++s) {
      columns[static_cast<std::size_t>(low.group_of[static_cast<std::size_t>(low.slot_row[s])])]
          .push_back(low.group_of[static_cast<std::size_t>(low.slot_column[s])]);
    }
    std::vector<int> rows;
    std::vector<int> flat;
    std::vector<std::size_t> row_first(groups + 1, 0);
    for (std::size_t g = 0; g < groups; ++g) {
      std::sort(columns[g].begin(), columns[g].end());
      columns[g].erase(std::unique(columns[g].begin(), columns[g].end()), columns[g].end());
      row_first[g + 1] = row_first[g] + columns[g].size();
      for (const int h : columns[g]) {
        rows.push_back(static_cast<int>(g));
        flat.push_back(h);
      }
    }
    set_pattern(rows, flat, groups, above.slot_row, above.slot_column, above.slot_first,
                above.diagonal_slot);
    low.group_slot.resize(low.slot_row.size());
    for (std::size_t s = 0; s < low.slot_row.size(); ++s) {
      const auto g =
          static_cast<std::size_t>(low.group_of[static_cast<std::size_t>(low.slot_row[s])]);
      const int h = low.group_of[static_cast<std::size_t>(low.slot_column[s])];
      const auto found = std::lower_bound(columns[g].begin(), columns[g].end(), h);
      low.group_slot[s] =
          static_cast<int>(row_first[g]) + static_cast<int>(found - columns[g].begin());
    }
    low.group_map.resize(low.size());
    low.own_inverse.resize(low.size());
    // Each slot's mirror (b, a), and each node's coupled groups in the order its slots first
    // reach them: set here, with the pattern, and read by every assemble().
    low.mirror_slot.resize(low.slot_row.size());
    for (std::size_t s = 0; s < low.slot_row.size(); ++s) {
      const auto b = static_cast<std::size_t>(low.slot_column[s]);
      const auto row_begin =
          low.slot_column.begin() + static_cast<std::ptrdiff_t>(low.slot_first[b]);
      const auto row_end =
          low.slot_column.begin() + static_cast<std::ptrdiff_t>(low.slot_first[b + 1]);
      const auto mirror = std::lower_bound(row_begin, row_end, low.slot_row[s]);
      INCISE_ASSERT(mirror != row_end && *mirror == low.slot_row[s],
                    "coarse pattern not symmetric");
      low.mirror_slot[s] = static_cast<int>(mirror - low.slot_column.begin());
    }
    low.coupling_first.assign(1, 0);
    low.coupling_group.clear();
    low.coupling_of_slot.resize(low.slot_row.size());
    std::vector<int> place(groups, -1);
    for (std::size_t a = 0; a < low.size(); ++a) {
      const std::size_t node_first = low.coupling_group.size();
      for (std::size_t s = low.slot_first[a]; s != low.slot_first[a + 1]; ++s) {
        const auto g =
            static_cast<std::size_t>(low.group_of[static_cast<std::size_t>(low.slot_column[s])]);
        if (place[g] < static_cast<int>(node_first)) {
          place[g] = static_cast<int>(low.coupling_group.size());
          low.coupling_group.push_back(static_cast<int>(g));
        }
        low.coupling_of_slot[s] = static_cast<std::size_t>(place[g]);
      }
      low.coupling_first.push_back(low.coupling_group.size());
    }
    low.coupling.resize(low.coupling_group.size());
    above.blocks.assign(flat.size(), ModeMatrix::Zero());
    above.centre.resize(groups);
    above.modes_from_raw.resize(groups);
    above.dropped.resize(groups);
  }
  levels_.push_back(std::move(above));
}

void CoarseCycle::build_exact() {
  // Scalar column 6a + c holds, for each coupled b and each r, entry (6b + r, 6a + c) =
  // block(b, a)(r, c) = block(a, b)(c, r) (the matrix is symmetric): offset 6 r + c of the
  // column-major block (a, b).
  const Level& top = levels_.back();
  const auto unknowns = static_cast<int>(kModes * top.size());
  std::vector<int> outer(static_cast<std::size_t>(unknowns) + 1, 0);
  std::vector<int> inner;
  scalar_source_.clear();
  for (std::size_t a = 0; a < top.size(); ++a) {
    for (int c = 0; c < kModes; ++c) {
      for (std::size_t s = top.slot_first[a]; s != top.slot_first[a + 1]; ++s) {
        const int b = top.slot_column[s];
        for (int r = 0; r < kModes; ++r) {
          inner.push_back(kModes * b + r);
          scalar_source_.emplace_back(static_cast<int>(s), kModes * r + c);
        }
      }
      outer[kModes * a + static_cast<std::size_t>(c) + 1] = static_cast<int>(inner.size());
    }
  }
  scalar_.resize(unknowns, unknowns);
  scalar_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), scalar_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), scalar_.innerIndexPtr());
}

bool CoarseCycle::assemble(std::span<const Vec3> centre,
                           std::span<const ModeMatrix> modes_from_raw) {
  for (std::size_t k = 0; k + 1 < levels_.size(); ++k) {
    if (k == 0) {
      shape_groups(0, centre, modes_from_raw);
    } else {
      shape_groups(k, levels_[k].centre, levels_[k].modes_from_raw);
    }
    prepare_smoother(k);
  }
  const Level& top = levels_.back();
  if (top.size() == 0) {
    return true;
  }
  double* target = scalar_.valuePtr();
  for (std::size_t s = 0; s < scalar_source_.size(); ++s) {
    const auto [slot, entry] = scalar_source_[s];
    target[s] = top.blocks[static_cast<std::size_t>(slot)].data()[entry];
  }
  return factor_->factorize_positive_definite(scalar_);
}

void CoarseCycle::shape_groups(std::size_t k, std::span<const Vec3> centre,
                               std::span<const ModeMatrix> modes_from_raw) {
  // A group's rigid motion (t, w) about its centre C moves node a rigidly with
  // (t + w x (c_a - C), w): its modes' coordinates are modes_from_raw_a of that. The group's
  // modes are those motions orthonormalised over its members.
  Level& low = levels_[k];
  Level& high = levels_[k + 1];
  parallel_for(0, high.size(), kGroupGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t g = first; g != last; ++g) {
      Vec3 group_centre = Vec3::Zero();
      for (std::size_t m = low.group_first[g]; m != low.group_first[g + 1]; ++m) {
        group_centre += centre[static_cast<std::size_t>(low.group_member[m])];
      }
      group_centre /= static_cast<double>(low.group_first[g + 1] - low.group_first[g]);
      high.centre[g] = group_centre;
      ModeMatrix gram = ModeMatrix::Zero();
      for (std::size_t m = low.group_first[g]; m != low.group_first[g + 1]; ++m) {
        const auto a = static_cast<std::size_t>(low.group_member[m]);
        ModeMatrix raw_from_group = ModeMatrix::Identity();
        raw_from_group.topRightCorner<3, 3>() = -cross_matrix(centre[a] - group_centre);
        low.group_map[a] = modes_from_raw[a] * raw_from_group;
        gram.noalias() += low.group_map[a].transpose() * low.group_map[a];
      }
      const OrthonormalModes modes = orthonormal_modes(gram);
      high.modes_from_raw[g] = modes.modes_from_raw;
      high.dropped[g] = modes.dropped;
      for (std::size_t m = low.group_first[g]; m != low.group_first[g + 1]; ++m) {
        const auto a = static_cast<std::size_t>(low.group_member[m]);
        low.group_map[a] = low.group_map[a] * modes.raw_from_modes;
      }
    }
  });
}

void CoarseCycle::prepare_smoother(std::size_t k) {
  Level& low = levels_[k];
  Level& high = levels_[k + 1];
  const std::size_t nodes = low.size();
  parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      const ModeMatrix inverse =
          Eigen::LLT<ModeMatrix>(low.blocks[static_cast<std::size_t>(low.diagonal_slot[a])])
              .solve(ModeMatrix::Identity());
      low.own_inverse[a] = 0.5 * (inverse + inverse.transpose());
    }
  });
  // The cycle is symmetric only if both its products use one symmetric matrix: block (b, a)
  // is taken as the transpose of block (a, b) for a < b (the sums behind the two differ in
  // their last bits, which rounding can make a level apart), and the group correction's
  // product below uses these rounded blocks too.
  resize_for_edits(low.quantized_blocks, low.blocks.size());
  parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      for (std::size_t s = low.slot_first[a]; s != low.slot_first[a + 1]; ++s) {
        const auto b = static_cast<std::size_t>(low.slot_column[s]);
        if (b == a) {
          low.quantized_blocks[s] = quantize(0.5 * (low.blocks[s] + low.blocks[s].transpose()));
        } else if (a < b) {
          low.quantized_blocks[s] = quantize(low.blocks[s]);
        } else {
          low.quantized_blocks[s] =
              quantize(low.blocks[static_cast<std::size_t>(low.mirror_slot[s])].transpose());
        }
      }
    }
  });
  parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      for (std::size_t c = low.coupling_first[a]; c != low.coupling_first[a + 1]; ++c) {
        low.coupling[c].setZero();
      }
      for (std::size_t s = low.slot_first[a]; s != low.slot_first[a + 1]; ++s) {
        low.coupling[low.coupling_of_slot[s]].noalias() +=
            dequantize(low.quantized_blocks[s]) *
            low.group_map[static_cast<std::size_t>(low.slot_column[s])];
      }
    }
  });
  const double reach = smoother_reach(k);
  if (reach > kSmootherReach) {
    const double damping = kSmootherReach / reach;
    for (ModeMatrix& inverse : low.own_inverse) {
      inverse *= damping;
    }
  }
  // The level above's matrix Q^T A Q, group row by group row (its members in order, each
  // member's slots in order: one task per row, deterministic).
  parallel_for(0, high.size(), kGroupGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t g = first; g != last; ++g) {
      for (std::size_t s = high.slot_first[g]; s != high.slot_first[g + 1]; ++s) {
        high.blocks[s].setZero();
      }
      for (std::size_t m = low.group_first[g]; m != low.group_first[g + 1]; ++m) {
        const auto a = static_cast<std::size_t>(low.group_member[m]);
        const ModeMatrix left = low.group_map[a].transpose();
        for (std::size_t s = low.slot_first[a]; s != low.slot_first[a + 1]; ++s) {
          high.blocks[static_cast<std::size_t>(low.group_slot[s])].noalias() +=
              left * low.blocks[s] * low.group_map[static_cast<std::size_t>(low.slot_column[s])];
        }
      }
      fill_dropped(high.blocks[static_cast<std::size_t>(high.diagonal_slot[g])], high.dropped[g]);
    }
  });
}

Modes CoarseCycle::residual_of(const Level& level, std::size_t a, const Modes& c,
                               const std::vector<Modes>& y) {
  return subtract_quantized_products(level.quantized_blocks.data(), level.slot_column.data(),
                                     level.slot_first[a], level.slot_first[a + 1], y.data(), c);
}

double CoarseCycle::smoother_reach(std::size_t k) const {
  // Power iteration on L A from a fixed rough start (a smooth one holds little of the top
  // eigenvector; minstd_rand's sequence is the same everywhere, so is the damping): twelve
  // steps put it within a few per cent of the largest eigenvalue on the peers' box, which the
  // margin below 2 in kSmootherReach covers.
  const Level& level = levels_[k];
  const std::size_t nodes = level.size();
  std::vector<Modes> x(nodes);
  std::minstd_rand sequence(7);
  for (Modes& entry : x) {
    for (int m = 0; m < kModes; ++m) {
      entry(m) = 2.0 * static_cast<double>(sequence() - std::minstd_rand::min()) /
                     static_cast<double>(std::minstd_rand::max() - std::minstd_rand::min()) -
                 1.0;
    }
  }
  std::vector<Modes> product(nodes);
  double estimate = 0.0;
  for (int step = 0; step < 12; ++step) {
    parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
      for (std::size_t a = first; a != last; ++a) {
        product[a] = -(level.own_inverse[a] * residual_of(level, a, Modes::Zero(), x));
      }
    });
    double before = 0.0;
    double after = 0.0;
    for (std::size_t a = 0; a < nodes; ++a) {
      before += x[a].squaredNorm();
      after += product[a].squaredNorm();
    }
    if (before <= 0.0 || after <= 0.0) {
      return estimate;
    }
    estimate = std::sqrt(after / before);
    const double scale = 1.0 / std::sqrt(after);
    for (std::size_t a = 0; a < nodes; ++a) {
      x[a] = scale * product[a];
    }
  }
  return estimate;
}

void CoarseCycle::solve(std::span<const Modes> rhs, std::span<Modes> solution) {
  Level& base = levels_.front();
  INCISE_ASSERT(rhs.size() == base.size() && solution.size() == base.size(),
                "one right-hand side and one solution per aggregate");
  base.rhs.assign(rhs.begin(), rhs.end());
  cycle(0);
  std::copy(base.solution.begin(), base.solution.end(), solution.begin());
}

void CoarseCycle::solve_groups(std::size_t k) {
  if (k + 1 == levels_.size()) {
    cycle(k);  // exact
    return;
  }
  // Two cycles: y = B c, y += B (c - A y). B is symmetric, so is this (2B - B A B), and
  // positive definite as the cycle converges.
  Level& level = levels_[k];
  const std::size_t nodes = level.size();
  cycle(k);
  level.first_rhs.swap(level.rhs);
  level.first_solution.swap(level.solution);
  level.rhs.resize(nodes);
  parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      level.rhs[a] = residual_of(level, a, level.first_rhs[a], level.first_solution);
    }
  });
  cycle(k);
  for (std::size_t a = 0; a < nodes; ++a) {
    level.solution[a] += level.first_solution[a];
  }
}

void CoarseCycle::cycle(std::size_t k) {
  Level& low = levels_[k];
  const std::size_t nodes = low.size();
  low.solution.resize(nodes);
  if (k + 1 == levels_.size()) {
    top_rhs_.resize(static_cast<Eigen::Index>(kModes * nodes));
    for (std::size_t a = 0; a < nodes; ++a) {
      top_rhs_.segment<kModes>(static_cast<Eigen::Index>(kModes * a)) = low.rhs[a];
    }
    const Eigen::VectorXd exact = factor_->solve(top_rhs_);
    for (std::size_t a = 0; a < nodes; ++a) {
      low.solution[a] = exact.segment<kModes>(static_cast<Eigen::Index>(kModes * a));
    }
    return;
  }
  // One symmetric V-cycle on A y = c: y = w L c (each node's own block), y += Q (the level
  // above's solution for Q^T (c - A y)), y += w L (c - A y).
  Level& high = levels_[k + 1];
  low.residual.resize(nodes);
  high.rhs.resize(high.size());
  parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      low.solution[a].noalias() = low.own_inverse[a] * low.rhs[a];
    }
  });
  // By group: its nodes' residuals after the smoothing, and their part of its right-hand side
  // (in member order).
  parallel_for(0, high.size(), kGroupGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t g = first; g != last; ++g) {
      Modes group_rhs = Modes::Zero();
      for (std::size_t m = low.group_first[g]; m != low.group_first[g + 1]; ++m) {
        const auto a = static_cast<std::size_t>(low.group_member[m]);
        low.residual[a] = residual_of(low, a, low.rhs[a], low.solution);
        group_rhs.noalias() += low.group_map[a].transpose() * low.residual[a];
      }
      high.rhs[g] = group_rhs;
    }
  });
  solve_groups(k + 1);
  // y += Q e; then c - A (y + Q e) = (c - A y) - A Q e, with (A Q e)_a = sum over its coupled
  // groups g of K_ag e_g; y += w L of that.
  parallel_for(0, nodes, kNodeGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      low.solution[a].noalias() +=
          low.group_map[a] * high.solution[static_cast<std::size_t>(low.group_of[a])];
      Modes left = low.residual[a];
      for (std::size_t c = low.coupling_first[a]; c != low.coupling_first[a + 1]; ++c) {
        left.noalias() -=
            low.coupling[c] * high.solution[static_cast<std::size_t>(low.coupling_group[c])];
      }
      low.solution[a].noalias() += low.own_inverse[a] * left;
    }
  });
}

}  // namespace incise::coarse
