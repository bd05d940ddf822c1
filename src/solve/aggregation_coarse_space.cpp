#include "incise/solve/aggregation_coarse_space.hpp"

#include <algorithm>

#include "incise/core/parallel_for.hpp"
#include "incise/solve/direct_factorization.hpp"

namespace incise {

AggregationCoarseSpace::AggregationCoarseSpace()
    : factor_(std::make_unique<DirectFactorization>()) {}

AggregationCoarseSpace::~AggregationCoarseSpace() = default;

void AggregationCoarseSpace::aggregate(const BlockSparseMatrix& matrix,
                                       std::span<const char> constrained) {
  const std::size_t n = matrix.rows();
  aggregate_of_.assign(n, -1);
  members_.clear();
  auto is_free = [&](VertexId v) { return constrained[static_cast<std::size_t>(v)] == 0; };
  // 1. A vertex whose free neighbours are all still unclaimed founds an aggregate with them:
  //    aggregates of about one ring, spread over the body without overlap.
  for (std::size_t i = 0; i < n; ++i) {
    const auto vertex = static_cast<VertexId>(i);
    if (!is_free(vertex) || aggregate_of_[i] >= 0) {
      continue;
    }
    const auto row = matrix.row_columns(vertex);
    const bool all_unclaimed = std::all_of(row.begin(), row.end(), [&](VertexId j) {
      return !is_free(j) || aggregate_of_[static_cast<std::size_t>(j)] < 0;
    });
    if (!all_unclaimed) {
      continue;
    }
    const int id = static_cast<int>(members_.size());
    std::vector<VertexId>& group = members_.emplace_back();
    for (const VertexId j : row) {
      if (is_free(j)) {
        aggregate_of_[static_cast<std::size_t>(j)] = id;
        group.push_back(j);
      }
    }
  }
  // 2. The rest join the aggregate they are most strongly coupled to (largest block norm),
  //    among those of step 1, so aggregates do not creep.
  const std::vector<int> founded = aggregate_of_;
  const auto values = matrix.values();
  for (std::size_t i = 0; i < n; ++i) {
    const auto vertex = static_cast<VertexId>(i);
    if (!is_free(vertex) || founded[i] >= 0) {
      continue;
    }
    const auto row = matrix.row_columns(vertex);
    const std::size_t first = matrix.row_begin()[i];
    int best = -1;
    double strongest = -1.0;
    for (std::size_t k = 0; k < row.size(); ++k) {
      const auto j = static_cast<std::size_t>(row[k]);
      if (founded[j] >= 0 && is_free(row[k])) {
        const double strength = values[first + k].squaredNorm();
        if (strength > strongest) {
          strongest = strength;
          best = founded[j];
        }
      }
    }
    if (best >= 0) {
      aggregate_of_[i] = best;
      members_[static_cast<std::size_t>(best)].push_back(vertex);
    }
  }
  // 3. Vertices with no aggregate beside them (small loose pieces) group with their
  //    unclaimed neighbours.
  for (std::size_t i = 0; i < n; ++i) {
    const auto vertex = static_cast<VertexId>(i);
    if (!is_free(vertex) || aggregate_of_[i] >= 0) {
      continue;
    }
    const int id = static_cast<int>(members_.size());
    std::vector<VertexId>& group = members_.emplace_back();
    for (const VertexId j : matrix.row_columns(vertex)) {
      if (is_free(j) && aggregate_of_[static_cast<std::size_t>(j)] < 0) {
        aggregate_of_[static_cast<std::size_t>(j)] = id;
        group.push_back(j);
      }
    }
  }
  for (std::vector<VertexId>& group : members_) {
    std::sort(group.begin(), group.end());
  }

  // The coarse pattern: aggregate I couples to J when a block of A joins a member of each.
  // Slots are numbered row by row with sorted columns, so the scalar matrix comes out sorted.
  const std::size_t aggregates = members_.size();
  coarse_slot_.assign(matrix.values().size(), -1);
  std::vector<int> seen(aggregates, -1);
  std::vector<int> slot_of(aggregates, -1);
  std::vector<int> neighbours;
  std::vector<std::vector<int>> coarse_columns(aggregates);
  int slots = 0;
  for (std::size_t a = 0; a < aggregates; ++a) {
    neighbours.clear();
    for (const VertexId v : members_[a]) {
      for (const VertexId j : matrix.row_columns(v)) {
        const int b = aggregate_of_[static_cast<std::size_t>(j)];
        if (b >= 0 && seen[static_cast<std::size_t>(b)] != static_cast<int>(a)) {
          seen[static_cast<std::size_t>(b)] = static_cast<int>(a);
          neighbours.push_back(b);
        }
      }
    }
    std::sort(neighbours.begin(), neighbours.end());
    for (const int b : neighbours) {
      slot_of[static_cast<std::size_t>(b)] = slots++;
    }
    for (const VertexId v : members_[a]) {
      const std::size_t first = matrix.row_begin()[static_cast<std::size_t>(v)];
      const auto row = matrix.row_columns(v);
      for (std::size_t k = 0; k < row.size(); ++k) {
        const int b = aggregate_of_[static_cast<std::size_t>(row[k])];
        if (b >= 0) {
          coarse_slot_[first + k] = slot_of[static_cast<std::size_t>(b)];
        }
      }
    }
    coarse_columns[a] = neighbours;
  }
  coarse_blocks_.assign(static_cast<std::size_t>(slots), Mat3::Zero());

  // Scalar column 3a + c holds, for each coupled b and each r, entry (3b + r, 3a + c) =
  // block(b, a)(r, c) = block(a, b)(c, r) (the matrix is symmetric): offset 3 r + c of the
  // column-major block (a, b).
  const auto unknowns = static_cast<int>(3 * aggregates);
  std::vector<int> outer(static_cast<std::size_t>(unknowns) + 1, 0);
  std::vector<int> inner;
  scalar_source_.clear();
  int slot = 0;
  for (std::size_t a = 0; a < aggregates; ++a) {
    const int row_slot = slot;
    for (int c = 0; c < 3; ++c) {
      int s = row_slot;
      for (const int b : coarse_columns[a]) {
        for (int r = 0; r < 3; ++r) {
          inner.push_back(3 * b + r);
          scalar_source_.emplace_back(s, 3 * r + c);
        }
        ++s;
      }
      outer[3 * a + static_cast<std::size_t>(c) + 1] = static_cast<int>(inner.size());
    }
    slot += static_cast<int>(coarse_columns[a].size());
  }
  scalar_.resize(unknowns, unknowns);
  scalar_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), scalar_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), scalar_.innerIndexPtr());
  factor_->reset_pattern();
  coarse_solution_.assign(aggregates, Vec3::Zero());
  ++aggregations_;
}

void AggregationCoarseSpace::extend(const BlockSparseMatrix& matrix,
                                    std::span<const char> constrained) {
  // New vertices (a cut) join the aggregate of their most strongly coupled neighbour that has
  // one; vertices held since are dropped. The aggregates, and so the factor, stay as they are:
  // a vertex with no aggregate beside it gets no coarse correction until the next
  // refactorisation.
  const std::size_t n = matrix.rows();
  aggregate_of_.resize(n, -1);
  const auto values = matrix.values();
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained[i] != 0) {
      aggregate_of_[i] = -1;
      continue;
    }
    if (aggregate_of_[i] >= 0) {
      continue;
    }
    const auto row = matrix.row_columns(static_cast<VertexId>(i));
    const std::size_t first = matrix.row_begin()[i];
    double strongest = -1.0;
    for (std::size_t k = 0; k < row.size(); ++k) {
      const int other = aggregate_of_[static_cast<std::size_t>(row[k])];
      if (other >= 0 && constrained[static_cast<std::size_t>(row[k])] == 0 &&
          values[first + k].squaredNorm() > strongest) {
        strongest = values[first + k].squaredNorm();
        aggregate_of_[i] = other;
      }
    }
  }
  for (std::vector<VertexId>& group : members_) {
    group.clear();
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (aggregate_of_[i] >= 0) {
      members_[static_cast<std::size_t>(aggregate_of_[i])].push_back(static_cast<VertexId>(i));
    }
  }
}

bool AggregationCoarseSpace::update(const BlockSparseMatrix& matrix,
                                    std::span<const char> constrained) {
  auto same_as = [&](const Look& look) {
    return look.pattern == matrix.pattern() && look.version == matrix.pattern_version() &&
           std::equal(constrained.begin(), constrained.end(), look.constrained.begin(),
                      look.constrained.end());
  };
  auto remember = [&](Look& look) {
    look.pattern = matrix.pattern();
    look.version = matrix.pattern_version();
    look.constrained.assign(constrained.begin(), constrained.end());
  };
  const bool due = !factored_ || ++updates_since_factor_ >= refactor_every_ ||
                   matrix.rows() < aggregate_of_.size();
  if (!due) {
    // The factor of an earlier matrix is a good preconditioner still (the corotational
    // matrix changes with the elements' rotations, slowly; a cut changes it near the blade).
    if (!same_as(seen_)) {
      extend(matrix, constrained);
      remember(seen_);
    }
    return true;
  }
  if (!same_as(aggregated_)) {
    aggregate(matrix, constrained);
    remember(aggregated_);
    remember(seen_);
  }
  updates_since_factor_ = 0;
  factored_ = true;
  // P^T A P: each aggregate's coarse row from its members' rows (rows in parallel, each coarse
  // row summed in member order by one thread: deterministic).
  const auto values = matrix.values();
  const auto row_begin = matrix.row_begin();
  const auto row_end = matrix.row_end();
  std::fill(coarse_blocks_.begin(), coarse_blocks_.end(), Mat3::Zero());
  parallel_for(0, members_.size(), 64, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      for (const VertexId v : members_[a]) {
        const auto i = static_cast<std::size_t>(v);
        for (std::size_t k = row_begin[i]; k < row_end[i]; ++k) {
          const int slot = coarse_slot_[k];
          if (slot >= 0) {
            coarse_blocks_[static_cast<std::size_t>(slot)] += values[k];
          }
        }
      }
    }
  });
  double* target = scalar_.valuePtr();
  for (std::size_t s = 0; s < scalar_source_.size(); ++s) {
    const auto [slot, entry] = scalar_source_[s];
    target[s] = coarse_blocks_[static_cast<std::size_t>(slot)].data()[entry];
  }
  return members_.empty() || factor_->factorize_positive_definite(scalar_);
}

void AggregationCoarseSpace::add_correction(std::span<Vec3> z) const {
  for (std::size_t a = 0; a < members_.size(); ++a) {
    const Vec3& correction = coarse_solution_[a];
    for (const VertexId v : members_[a]) {
      z[static_cast<std::size_t>(v)] += correction;
    }
  }
}

double AggregationCoarseSpace::solve(std::span<const Vec3> residual) {
  const std::size_t aggregates = members_.size();
  if (aggregates == 0) {
    return 0.0;
  }
  coarse_rhs_.resize(static_cast<Eigen::Index>(3 * aggregates));
  // P^T r on the calling thread (lighter than handing it to the workers).
  for (std::size_t a = 0; a < aggregates; ++a) {
    Vec3 sum = Vec3::Zero();
    for (const VertexId v : members_[a]) {
      sum += residual[static_cast<std::size_t>(v)];
    }
    coarse_rhs_.segment<3>(static_cast<Eigen::Index>(3 * a)) = sum;
  }
  const Eigen::VectorXd solution = factor_->solve(coarse_rhs_);
  for (std::size_t a = 0; a < aggregates; ++a) {
    coarse_solution_[a] = solution.segment<3>(static_cast<Eigen::Index>(3 * a));
  }
  return coarse_rhs_.dot(solution);
}

}  // namespace incise
