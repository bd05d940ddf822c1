// The numeric supernodal Cholesky factorisation in single precision, on CHOLMOD's symbolic
// analysis (its ordering and supernodes). Written here because CHOLMOD 3 (Debian 12's
// SuiteSparse 5.12) factorises in double precision only, and on one core: a factor wanted as a
// preconditioner, to a few digits, costs half the bytes and half the BLAS time in floats, and
// the subtrees of the supernodes are independent. Left-looking: each supernode pulls the
// updates of the supernodes below it, in a fixed order, so that the factor does not depend on
// which thread made which subtree.

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "incise/core/parallel_for.hpp"
#include "single_precision_supernodes.hpp"

namespace incise {

void SinglePrecisionSupernodes::plan_factorization(
    const cholmod_factor& symbolic,
    const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& lower) {
  const SupernodeView l(symbolic);
  const auto n = static_cast<std::size_t>(symbolic.n);
  const auto* perm = static_cast<const int*>(symbolic.Perm);
  // P A P^T's lower triangle: A's entry (i, j) goes to (inverse[i], inverse[j]), in the column
  // of the smaller of the two.
  std::vector<int> inverse(n);
  for (std::size_t k = 0; k < n; ++k) {
    inverse[static_cast<std::size_t>(perm[k])] = static_cast<int>(k);
  }
  const auto entries = static_cast<std::size_t>(lower.nonZeros());
  std::vector<int> column_of(entries);
  std::vector<int> row_of(entries);
  permuted_start_.assign(n + 1, 0);
  for (int j = 0; j < lower.outerSize(); ++j) {
    for (int e = lower.outerIndexPtr()[j]; e < lower.outerIndexPtr()[j + 1]; ++e) {
      const int i = lower.innerIndexPtr()[e];
      const int a = inverse[static_cast<std::size_t>(i)];
      const int b = inverse[static_cast<std::size_t>(j)];
      column_of[static_cast<std::size_t>(e)] = std::min(a, b);
      row_of[static_cast<std::size_t>(e)] = std::max(a, b);
      ++permuted_start_[static_cast<std::size_t>(std::min(a, b)) + 1];
    }
  }
  for (std::size_t k = 0; k < n; ++k) {
    permuted_start_[k + 1] += permuted_start_[k];
  }
  permuted_row_.resize(entries);
  permuted_from_.resize(entries);
  std::vector<int> next(permuted_start_.begin(), permuted_start_.end() - 1);
  for (std::size_t e = 0; e < entries; ++e) {
    const int slot = next[static_cast<std::size_t>(column_of[e])]++;
    permuted_row_[static_cast<std::size_t>(slot)] = row_of[e];
    permuted_from_[static_cast<std::size_t>(slot)] = static_cast<int>(e);
  }
  permuted_values_.resize(entries);
  // Each supernode's rows below its block fall into ancestors' columns in runs (the rows are
  // sorted, the supernodes' columns consecutive): a run is an update to that ancestor.
  const std::vector<int> of_column = l.supernode_of_columns(n);
  std::vector<int> count(static_cast<std::size_t>(l.count) + 1, 0);
  const auto for_each_run = [&](int d, const auto& take) {
    const int* rows = l.rows + l.pi[d];
    const int height = l.height(d);
    for (int first = l.columns(d); first < height;) {
      const int target = of_column[static_cast<std::size_t>(rows[first])];
      int last = first + 1;
      while (last < height && rows[last] < l.super[target + 1]) {
        ++last;
      }
      take(target, first, last);
      first = last;
    }
  };
  for (int d = 0; d < l.count; ++d) {
    for_each_run(d, [&](int target, int, int) { ++count[static_cast<std::size_t>(target) + 1]; });
  }
  for (std::size_t s = 0; s < static_cast<std::size_t>(l.count); ++s) {
    count[s + 1] += count[s];
  }
  update_first_ = count;
  update_.resize(static_cast<std::size_t>(count.back()));
  for (int d = 0; d < l.count; ++d) {  // ascending: each supernode's updates in that order
    for_each_run(d, [&](int target, int first, int last) {
      update_[static_cast<std::size_t>(count[static_cast<std::size_t>(target)]++)] = {d, first,
                                                                                      last};
    });
  }
  maps_.assign(subtrees_.size() + 1, std::vector<int>(n, 0));
  products_.assign(subtrees_.size(), {});
  subtree_failed_.assign(subtrees_.size(), 0);
  plan_made_ = true;
}

namespace {

/// The top's supernodes are worked on in chunks of this many of their rows, side by side: a
/// fixed partition, so that every product is the same on any number of threads.
constexpr int kRowChunk = 256;
/// Their diagonal blocks are factorised in panels of this many columns.
constexpr int kPanel = 128;

using BlockMap = Eigen::Map<Eigen::MatrixXf, 0, Eigen::OuterStride<>>;

/// The chunks of rows [begin, end) of a block: fixed places (multiples of kRowChunk).
int first_chunk(int begin) {
  return begin / kRowChunk;
}
int chunk_count(int begin, int end) {
  return end > begin ? (end - 1) / kRowChunk + 1 - first_chunk(begin) : 0;
}

/// The positions of rows[0..count) whose place in the block (`map`) lies in [lower, upper):
/// a range, as the places rise with the position.
std::pair<int, int> rows_within(const int* rows, int count, const std::vector<int>& map, int lower,
                                int upper) {
  const auto first_placed_at = [&](int from, int place) {
    int low = from;
    int high = count;
    while (low < high) {
      const int middle = low + (high - low) / 2;
      if (map[static_cast<std::size_t>(rows[middle])] < place) {
        low = middle + 1;
      } else {
        high = middle;
      }
    }
    return low;
  };
  const int first = first_placed_at(0, lower);
  return {first, first_placed_at(first, upper)};
}

}  // namespace

void SinglePrecisionSupernodes::assemble_supernode(int s, std::vector<int>& map) {
  const SupernodeView l(*factor_);
  const int columns = l.columns(s);
  const int height = l.height(s);
  const int first_column = l.super[s];
  const int* rows = l.rows + l.pi[s];
  BlockMap block(values_.data() + l.px[s], height, columns, Eigen::OuterStride<>(height));
  for (int i = 0; i < height; ++i) {
    map[static_cast<std::size_t>(rows[i])] = i;
  }
  // The matrix's entries (each of its rows is among the supernode's, by the analysis).
  block.setZero();
  for (int c = 0; c < columns; ++c) {
    const auto k = static_cast<std::size_t>(first_column + c);
    for (int e = permuted_start_[k]; e < permuted_start_[k + 1]; ++e) {
      const auto slot = static_cast<std::size_t>(e);
      block(map[static_cast<std::size_t>(permuted_row_[slot])], c) += permuted_values_[slot];
    }
  }
}

void SinglePrecisionSupernodes::subtract_updates(int s, const std::vector<int>& map, int lower,
                                                 int upper, std::vector<float>& product) {
  const SupernodeView l(*factor_);
  const int height = l.height(s);
  const int first_column = l.super[s];
  BlockMap block(values_.data() + l.px[s], height, l.columns(s), Eigen::OuterStride<>(height));
  // The updates of the supernodes below, in ascending order: L_d[rows from `first`] times
  // L_d[rows first..last)^T, the lower part, subtracted where its rows and columns fall (here
  // only its rows that fall in the block's rows [lower, upper)).
  for (int u = update_first_[static_cast<std::size_t>(s)];
       u < update_first_[static_cast<std::size_t>(s) + 1]; ++u) {
    const Update& update = update_[static_cast<std::size_t>(u)];
    const int d = update.descendant;
    const int* d_rows = l.rows + l.pi[d] + update.first;
    const int m = l.height(d) - update.first;
    const int q = update.last - update.first;
    const auto [from, to] = rows_within(d_rows, m, map, lower, upper);
    if (from >= to) {
      continue;
    }
    const SupernodeView::Block below = l.block(d, values_);
    const std::size_t size = static_cast<std::size_t>(to - from) * static_cast<std::size_t>(q);
    if (product.size() < size) {
      product.resize(size);
    }
    Eigen::Map<Eigen::MatrixXf> c(product.data(), to - from, q);
    c.noalias() = below.middleRows(update.first + from, to - from) *
                  below.middleRows(update.first, q).transpose();
    for (int j = 0; j < q; ++j) {
      const int target_column = d_rows[j] - first_column;
      for (int i = std::max(j, from); i < to; ++i) {
        block(map[static_cast<std::size_t>(d_rows[i])], target_column) -= c(i - from, j);
      }
    }
  }
}

bool SinglePrecisionSupernodes::factorize_supernode(int s, std::vector<int>& map,
                                                    std::vector<float>& product) {
  assemble_supernode(s, map);
  const SupernodeView l(*factor_);
  const int columns = l.columns(s);
  const int height = l.height(s);
  subtract_updates(s, map, 0, height, product);
  // The diagonal block's Cholesky factor, in place, and the rows below solved against it.
  BlockMap block(values_.data() + l.px[s], height, columns, Eigen::OuterStride<>(height));
  auto diagonal = block.topRows(columns);
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXf, 0, Eigen::OuterStride<>>> llt(diagonal);
  if (llt.info() != Eigen::Success || !diagonal.diagonal().allFinite()) {
    return false;
  }
  if (height > columns) {
    diagonal.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(
        block.bottomRows(height - columns));
  }
  return true;
}

bool SinglePrecisionSupernodes::factorize_wide_supernode(int s, std::vector<int>& map) {
  assemble_supernode(s, map);
  const SupernodeView l(*factor_);
  const int columns = l.columns(s);
  const int height = l.height(s);
  BlockMap block(values_.data() + l.px[s], height, columns, Eigen::OuterStride<>(height));
  const auto chunk_product = [this](std::size_t chunk) -> std::vector<float>& {
    return chunk_products_[chunk];
  };
  const int chunks = chunk_count(0, height);
  if (chunk_products_.size() < static_cast<std::size_t>(chunks)) {
    chunk_products_.resize(static_cast<std::size_t>(chunks));
  }
  // The descendants' updates, chunk by chunk of the block's rows.
  parallel_for(0, static_cast<std::size_t>(chunks), 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t chunk = first; chunk < last; ++chunk) {
      const int lower = static_cast<int>(chunk) * kRowChunk;
      subtract_updates(s, map, lower, std::min(height, lower + kRowChunk), chunk_product(chunk));
    }
  });
  // Right-looking Cholesky of the block by panels: each panel's diagonal factorised, the rows
  // below solved against it, and what is right of it updated, chunk by chunk of rows.
  for (int panel = 0; panel < columns; panel += kPanel) {
    const int width = std::min(kPanel, columns - panel);
    auto diagonal = block.block(panel, panel, width, width);
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXf, 0, Eigen::OuterStride<>>> llt(diagonal);
    if (llt.info() != Eigen::Success || !diagonal.diagonal().allFinite()) {
      return false;
    }
    const int below = panel + width;
    const int first = first_chunk(below);
    const int count = chunk_count(below, height);
    parallel_for(0, static_cast<std::size_t>(count), 1, [&](std::size_t begin, std::size_t end) {
      for (std::size_t k = begin; k < end; ++k) {
        const int chunk = first + static_cast<int>(k);
        const int lower = std::max(below, chunk * kRowChunk);
        const int upper = std::min(height, (chunk + 1) * kRowChunk);
        auto rows = block.block(lower, panel, upper - lower, width);
        diagonal.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(rows);
      }
    });
    // What is right of the panel: columns [below, columns), rows from each column down.
    if (below >= columns) {
      continue;
    }
    parallel_for(0, static_cast<std::size_t>(count), 1, [&](std::size_t begin, std::size_t end) {
      for (std::size_t k = begin; k < end; ++k) {
        const int chunk = first + static_cast<int>(k);
        const int lower = std::max(below, chunk * kRowChunk);
        const int upper = std::min(height, (chunk + 1) * kRowChunk);
        const int right = std::min(upper, columns) - below;  // the columns these rows reach
        std::vector<float>& product = chunk_product(static_cast<std::size_t>(chunk));
        const std::size_t size =
            static_cast<std::size_t>(upper - lower) * static_cast<std::size_t>(right);
        if (product.size() < size) {
          product.resize(size);
        }
        Eigen::Map<Eigen::MatrixXf> c(product.data(), upper - lower, right);
        c.noalias() = block.block(lower, panel, upper - lower, width) *
                      block.block(below, panel, right, width).transpose();
        for (int j = 0; j < right; ++j) {
          for (int i = std::max(0, below + j - lower); i < upper - lower; ++i) {
            block(lower + i, below + j) -= c(i, j);
          }
        }
      }
    });
  }
  return true;
}

bool SinglePrecisionSupernodes::factorize(
    const cholmod_factor& symbolic,
    const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& lower) {
  factor_ = nullptr;
  if (symbolic.is_super == 0 || symbolic.itype != CHOLMOD_INT || symbolic.super == nullptr ||
      symbolic.px == nullptr || !lower.isCompressed() ||
      lower.rows() != static_cast<Eigen::Index>(symbolic.n)) {
    return false;
  }
  if (!split_made_) {
    split(symbolic);
    plan_made_ = false;
  }
  if (!plan_made_) {
    plan_factorization(symbolic, lower);
  }
  factor_ = &symbolic;
  values_.resize(symbolic.xsize);
  work_.resize(static_cast<Eigen::Index>(symbolic.n));
  const double* source = lower.valuePtr();
  for (std::size_t e = 0; e < permuted_values_.size(); ++e) {
    permuted_values_[e] = static_cast<float>(source[permuted_from_[e]]);
  }
  std::fill(subtree_failed_.begin(), subtree_failed_.end(), 0);
  parallel_for(0, subtrees_.size(), 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t k = first; k < last; ++k) {
      for (const int s : subtrees_[k]) {
        if (!factorize_supernode(s, maps_[k], products_[k])) {
          subtree_failed_[k] = 1;
          break;
        }
      }
    }
  });
  bool positive = std::none_of(subtree_failed_.begin(), subtree_failed_.end(),
                               [](char failed) { return failed != 0; });
  for (std::size_t t = 0; positive && t < top_.size(); ++t) {
    positive = factorize_wide_supernode(top_[t], maps_.back());
  }
  if (!positive) {
    factor_ = nullptr;
  }
  return positive;
}

}  // namespace incise
