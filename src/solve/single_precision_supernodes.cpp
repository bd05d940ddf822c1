#include "single_precision_supernodes.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numeric>

#include "incise/core/parallel_for.hpp"

namespace incise {

namespace {

/// How many subtrees the sweeps run side by side: a fixed number, so that the sums over them
/// (and so the answer) do not depend on the threads there are.
constexpr std::size_t kSubtrees = 16;

}  // namespace

void SinglePrecisionSupernodes::copy(const cholmod_factor& factor) {
  factor_ = nullptr;
  if (factor.is_super == 0 || factor.is_ll == 0 || factor.itype != CHOLMOD_INT ||
      factor.xtype != CHOLMOD_REAL || factor.dtype != CHOLMOD_DOUBLE || factor.x == nullptr) {
    return;
  }
  const auto* values = static_cast<const double*>(factor.x);
  values_.resize(factor.xsize);
  std::atomic<bool> representable = true;
  parallel_for(0, factor.xsize, std::size_t{1} << 16, [&](std::size_t first, std::size_t last) {
    bool finite = true;
    for (std::size_t i = first; i < last; ++i) {
      values_[i] = static_cast<float>(values[i]);
      finite = finite && std::isfinite(values_[i]);
    }
    if (!finite) {
      representable = false;
    }
  });
  if (!representable) {
    return;  // beyond a float's range (a factor of a matrix of 1e76 and more): solve in double
  }
  work_.resize(static_cast<Eigen::Index>(factor.n));
  if (!split_made_) {
    split(factor);
  }
  factor_ = &factor;
}

void SinglePrecisionSupernodes::split(const cholmod_factor& factor) {
  const SupernodeView l(factor);
  const auto n = static_cast<std::size_t>(factor.n);
  // The supernodal elimination tree: a supernode's parent holds its first row below its
  // diagonal block. Supernodes come children first.
  const std::vector<int> of_column = l.supernode_of_columns(n);
  std::vector<int> parent(static_cast<std::size_t>(l.count), -1);
  std::vector<std::vector<int>> children(static_cast<std::size_t>(l.count));
  std::vector<int> roots;
  std::vector<double> work(static_cast<std::size_t>(l.count), 0.0);  // nonzeros in the subtree
  for (int s = 0; s < l.count; ++s) {
    const auto us = static_cast<std::size_t>(s);
    work[us] += static_cast<double>(l.height(s)) * l.columns(s);
    if (l.height(s) > l.columns(s)) {
      parent[us] = of_column[static_cast<std::size_t>(*l.rows_below(s))];
      children[static_cast<std::size_t>(parent[us])].push_back(s);
      work[static_cast<std::size_t>(parent[us])] += work[us];
    } else {
      roots.push_back(s);
    }
  }
  // From the roots down: the heaviest subtree is replaced by its children (its root joins the
  // top) until there are kSubtrees of them or the heaviest is a leaf.
  std::vector<int> chosen = roots;
  std::vector<char> in_top(static_cast<std::size_t>(l.count), 0);
  while (chosen.size() < kSubtrees) {
    const auto heaviest = std::max_element(chosen.begin(), chosen.end(), [&](int a, int b) {
      return work[static_cast<std::size_t>(a)] < work[static_cast<std::size_t>(b)];
    });
    const int s = *heaviest;
    if (children[static_cast<std::size_t>(s)].empty()) {
      break;
    }
    chosen.erase(heaviest);
    in_top[static_cast<std::size_t>(s)] = 1;
    const auto& below = children[static_cast<std::size_t>(s)];
    chosen.insert(chosen.end(), below.begin(), below.end());
  }
  // Each supernode's subtree (-1 for the top), parents before children.
  std::vector<int> subtree(static_cast<std::size_t>(l.count), -1);
  std::sort(chosen.begin(), chosen.end());
  for (std::size_t k = 0; k < chosen.size(); ++k) {
    subtree[static_cast<std::size_t>(chosen[k])] = static_cast<int>(k);
  }
  for (int s = l.count - 1; s >= 0; --s) {
    const auto us = static_cast<std::size_t>(s);
    if (subtree[us] < 0 && in_top[us] == 0 && parent[us] >= 0) {
      subtree[us] = subtree[static_cast<std::size_t>(parent[us])];
    }
  }
  subtrees_.assign(chosen.size(), {});
  top_.clear();
  top_position_.assign(n, -1);
  top_columns_ = 0;
  for (int s = 0; s < l.count; ++s) {
    const int k = subtree[static_cast<std::size_t>(s)];
    if (k >= 0) {
      subtrees_[static_cast<std::size_t>(k)].push_back(s);
    } else {
      top_.push_back(s);
      for (int c = l.super[s]; c < l.super[s + 1]; ++c) {
        top_position_[static_cast<std::size_t>(c)] = top_columns_++;
      }
    }
  }
  top_sums_.assign(subtrees_.size() * static_cast<std::size_t>(top_columns_), 0.0F);
  below_.assign(subtrees_.size() * std::max<std::size_t>(factor.maxesize, 1), 0.0F);
  split_made_ = true;
}

void SinglePrecisionSupernodes::forward(int s, float* top_sums, float* below_values) {
  const SupernodeView l(*factor_);
  const int columns = l.columns(s);
  const SupernodeView::Block block = l.block(s, values_);
  auto y = work_.segment(l.super[s], columns);
  block.topRows(columns).triangularView<Eigen::Lower>().solveInPlace(y);
  const int below = l.height(s) - columns;
  if (below == 0) {
    return;
  }
  Eigen::Map<Eigen::VectorXf> updates(below_values, below);
  updates.noalias() = block.bottomRows(below) * y;
  const int* below_rows = l.rows_below(s);
  for (int i = 0; i < below; ++i) {
    const float update = updates[i];
    const int row = below_rows[i];
    const int top = top_sums != nullptr ? top_position_[static_cast<std::size_t>(row)] : -1;
    if (top >= 0) {
      top_sums[top] += update;  // a subtree's update to the top: summed apart, added in order
    } else {
      work_[row] -= update;
    }
  }
}

void SinglePrecisionSupernodes::backward(int s, float* below_values) {
  const SupernodeView l(*factor_);
  const int columns = l.columns(s);
  const SupernodeView::Block block = l.block(s, values_);
  auto y = work_.segment(l.super[s], columns);
  const int below = l.height(s) - columns;
  if (below > 0) {
    const int* below_rows = l.rows_below(s);
    for (int i = 0; i < below; ++i) {
      below_values[i] = work_[below_rows[i]];
    }
    y.noalias() -= block.bottomRows(below).transpose() *
                   Eigen::Map<const Eigen::VectorXf>(below_values, below);
  }
  block.topRows(columns).triangularView<Eigen::Lower>().transpose().solveInPlace(y);
}

Eigen::VectorXd SinglePrecisionSupernodes::solve(const Eigen::VectorXd& b) {
  const auto n = static_cast<Eigen::Index>(factor_->n);
  const auto* perm = static_cast<const int*>(factor_->Perm);
  for (Eigen::Index k = 0; k < n; ++k) {
    work_[k] = static_cast<float>(b[perm[k]]);
  }
  const auto columns = static_cast<std::size_t>(top_columns_);
  const std::size_t room = below_.size() / std::max<std::size_t>(subtrees_.size(), 1);
  // L y = P b: the subtrees side by side, their updates to the top summed apart; then the top.
  std::fill(top_sums_.begin(), top_sums_.end(), 0.0F);
  parallel_for(0, subtrees_.size(), 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t k = first; k < last; ++k) {
      for (const int s : subtrees_[k]) {
        forward(s, top_sums_.data() + k * columns, below_.data() + k * room);
      }
    }
  });
  const SupernodeView l(*factor_);
  for (const int s : top_) {
    for (int c = l.super[s]; c < l.super[s + 1]; ++c) {
      const auto place = static_cast<std::size_t>(top_position_[static_cast<std::size_t>(c)]);
      for (std::size_t k = 0; k < subtrees_.size(); ++k) {
        work_[c] -= top_sums_[k * columns + place];
      }
    }
    forward(s, nullptr, below_.data());
  }
  // L^T z = y: the top, then the subtrees side by side (each reads the top, writes its own).
  for (auto s = top_.rbegin(); s != top_.rend(); ++s) {
    backward(*s, below_.data());
  }
  parallel_for(0, subtrees_.size(), 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t k = first; k < last; ++k) {
      for (auto s = subtrees_[k].rbegin(); s != subtrees_[k].rend(); ++s) {
        backward(*s, below_.data() + k * room);
      }
    }
  });
  Eigen::VectorXd x(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    x[perm[k]] = static_cast<double>(work_[k]);
  }
  return x;
}

}  // namespace incise
