#include "point_block_matrix.hpp"

#include <Eigen/SparseCore>
#include <algorithm>
#include <cstddef>
#include <cstdlib>

#include "incise/core/error.hpp"

namespace incise::planning {

PointBlockMatrix::PointBlockMatrix(std::vector<int> first_row, int rows,
                                   std::span<const std::pair<int, int>> pairs)
    : first_row_(std::move(first_row)), matrix_(rows, rows) {
  // The compressed lower triangle is written directly (the rows of each column ascending, as
  // Eigen's setFromTriplets would leave them): at 59k points, 360k pairs, the triplets' bucket
  // sort and the slots' binary searches took 82 ms, twice per plan (equilibrium and prediction).
  // Block column b holds columns 3b to 3b + 2: its point's diagonal block, then the blocks of
  // the pairs whose other point has the larger rows, in row order.
  const std::size_t n = first_row_.size();
  const auto block_columns = static_cast<std::size_t>(rows / 3);
  std::vector<int> point_of_block(block_columns, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const int r0 = first_row_[i];
    if (r0 >= 0) {
      INCISE_ASSERT(
          r0 % 3 == 0 && r0 + 3 <= rows && point_of_block[static_cast<std::size_t>(r0 / 3)] < 0,
          "PointBlockMatrix: first rows must be distinct multiples of 3 below rows");
      point_of_block[static_cast<std::size_t>(r0 / 3)] = static_cast<int>(i);
    }
  }
  // Per block column, the pairs below its diagonal block: (their larger row, pair).
  std::vector<std::size_t> begin(block_columns + 1, 0);
  const auto low_high = [&](std::size_t p) {
    const int ra = row(pairs[p].first);
    const int rb = row(pairs[p].second);
    if (ra < 0 || rb < 0 || ra == rb) {
      return std::pair{-1, -1};
    }
    return std::pair{std::min(ra, rb), std::max(ra, rb)};
  };
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const auto [low, high] = low_high(p);
    if (low >= 0) {
      ++begin[static_cast<std::size_t>(low / 3) + 1];
    }
  }
  for (std::size_t b = 0; b < block_columns; ++b) {
    begin[b + 1] += begin[b];
  }
  std::vector<std::pair<int, std::size_t>> below(begin[block_columns]);
  {
    std::vector<std::size_t> next(begin.begin(), begin.end() - 1);
    for (std::size_t p = 0; p < pairs.size(); ++p) {
      const auto [low, high] = low_high(p);
      if (low >= 0) {
        below[next[static_cast<std::size_t>(low / 3)]++] = {high, p};
      }
    }
  }
  // Sorted by row; a pair given twice shares its block (as the triplets' sum would): place[k]
  // is below[k]'s block among its column's distinct rows, distinct[b] their count. (A pair's
  // smaller row is a point's in the system: block columns without one hold nothing.)
  std::vector<int> place(below.size());
  std::vector<int> distinct(block_columns, 0);
  for (std::size_t b = 0; b < block_columns; ++b) {
    std::sort(below.begin() + static_cast<std::ptrdiff_t>(begin[b]),
              below.begin() + static_cast<std::ptrdiff_t>(begin[b + 1]));
    for (std::size_t k = begin[b]; k < begin[b + 1]; ++k) {
      distinct[b] += k == begin[b] || below[k].first != below[k - 1].first ? 1 : 0;
      place[k] = distinct[b] - 1;
    }
  }
  int* outer = matrix_.outerIndexPtr();
  outer[0] = 0;
  for (std::size_t b = 0; b < block_columns; ++b) {
    for (int c = 0; c < 3; ++c) {
      const std::size_t column = 3 * b + static_cast<std::size_t>(c);
      outer[column + 1] = outer[column] + (point_of_block[b] >= 0 ? 3 - c : 0) + 3 * distinct[b];
    }
  }
  matrix_.resizeNonZeros(outer[rows]);
  std::fill(matrix_.valuePtr(), matrix_.valuePtr() + matrix_.nonZeros(), 0.0);
  int* inner = matrix_.innerIndexPtr();
  diagonal_first_.assign(n, -1);
  coupling_first_.assign(pairs.size(), -1);
  below_diagonal_.assign(block_columns, 0);
  coupling_transposed_.assign(pairs.size(), 0);
  coupling_column_.assign(pairs.size(), -1);
  // Column r0 + c holds the diagonal block's rows r0 + c to r0 + 2, then 3 rows per block
  // below: (r, c) of the diagonal block sits at (r - c), a pair's (r, c) at 3 place + r after
  // the diagonal's 3 - c entries. A pair given twice writes the same rows twice.
  for (std::size_t b = 0; b < block_columns; ++b) {
    if (point_of_block[b] < 0) {
      continue;
    }
    const int r0 = 3 * static_cast<int>(b);
    below_diagonal_[b] = distinct[b];
    diagonal_first_[static_cast<std::size_t>(point_of_block[b])] = outer[r0];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c <= r; ++c) {
        inner[outer[r0 + c] + (r - c)] = r0 + r;
      }
    }
    for (std::size_t k = begin[b]; k < begin[b + 1]; ++k) {
      const auto [high, p] = below[k];
      coupling_transposed_[p] = row(pairs[p].first) < row(pairs[p].second) ? 1 : 0;
      coupling_column_[p] = r0;
      coupling_first_[p] = outer[r0] + 3 + 3 * place[k];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
          inner[outer[r0 + c] + (3 - c) + 3 * place[k] + r] = high + r;
        }
      }
    }
  }
}

void PointBlockMatrix::clear() {
  std::fill(matrix_.valuePtr(), matrix_.valuePtr() + matrix_.nonZeros(), 0.0);
}

PointBlockMatrix::Target PointBlockMatrix::diagonal_target(int point) const {
  const int first = diagonal_first_[static_cast<std::size_t>(point)];
  if (first < 0) {
    return {};
  }
  return {first, 2 + 3 * below_diagonal_[static_cast<std::size_t>(row(point) / 3)]};
}

PointBlockMatrix::Target PointBlockMatrix::coupling_target(std::size_t pair, bool as_given) const {
  const int first = coupling_first_[pair];
  if (first < 0) {
    return {};
  }
  const int step = 2 + 3 * below_diagonal_[static_cast<std::size_t>(coupling_column_[pair] / 3)];
  const bool transposed = (coupling_transposed_[pair] != 0) == as_given;
  return {first, transposed ? -step : step};
}

void PointBlockMatrix::add_diagonal(const Target& target, const Mat3& block) {
  if (target.first < 0) {
    return;
  }
  double* column = matrix_.valuePtr() + target.first;
  column[0] += block(0, 0);
  column[1] += block(1, 0);
  column[2] += block(2, 0);
  column += target.step;
  column[1] += block(1, 1);
  column[2] += block(2, 1);
  column += target.step - 1;
  column[2] += block(2, 2);
}

void PointBlockMatrix::add_coupling(const Target& target, const Mat3& block) {
  if (target.first < 0) {
    return;
  }
  double* column = matrix_.valuePtr() + target.first;
  const bool transposed = target.step < 0;
  const int step = std::abs(target.step);
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      column[r] += transposed ? block(c, r) : block(r, c);
    }
    column += c == 0 ? step : step - 1;
  }
}

void PointBlockMatrix::add_diagonal(int point, const Mat3& block) {
  add_diagonal(diagonal_target(point), block);
}

void PointBlockMatrix::add_coupling(std::size_t pair, const Mat3& block) {
  add_coupling(coupling_target(pair, true), block);
}

void PointBlockMatrix::damp_diagonal(double relative, double absolute) {
  double* values = matrix_.valuePtr();
  for (std::size_t i = 0; i < first_row_.size(); ++i) {
    const Target target = diagonal_target(static_cast<int>(i));
    if (target.first < 0) {
      continue;
    }
    // (0, 0), (1, 1) and (2, 2) at first, first + step + 1, first + 2 step + 1.
    for (const int offset : {0, target.step + 1, 2 * target.step + 1}) {
      double& diagonal = values[target.first + offset];
      diagonal += relative * diagonal + absolute;
    }
  }
}

}  // namespace incise::planning
