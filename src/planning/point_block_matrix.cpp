#include "point_block_matrix.hpp"

#include <Eigen/SparseCore>
#include <algorithm>

namespace incise::planning {

PointBlockMatrix::PointBlockMatrix(std::vector<int> first_row, int rows,
                                   std::span<const std::pair<int, int>> pairs)
    : first_row_(std::move(first_row)), matrix_(rows, rows) {
  const std::size_t n = first_row_.size();
  std::vector<Eigen::Triplet<double>> pattern;
  pattern.reserve(n * 6 + pairs.size() * 9);
  for (std::size_t i = 0; i < n; ++i) {
    const int r0 = first_row_[i];
    for (int r = 0; r < 3 && r0 >= 0; ++r) {
      for (int c = 0; c <= r; ++c) {
        pattern.emplace_back(r0 + r, r0 + c, 0.0);
      }
    }
  }
  for (const auto& [a, b] : pairs) {
    const int ra = row(a);
    const int rb = row(b);
    for (int r = 0; r < 3 && ra >= 0 && rb >= 0 && ra != rb; ++r) {
      for (int c = 0; c < 3; ++c) {
        pattern.emplace_back(std::max(ra, rb) + r, std::min(ra, rb) + c, 0.0);
      }
    }
  }
  matrix_.setFromTriplets(pattern.begin(), pattern.end());
  matrix_.makeCompressed();
  auto slot = [&](int r, int c) {
    const int* begin = matrix_.innerIndexPtr() + matrix_.outerIndexPtr()[c];
    const int* end = matrix_.innerIndexPtr() + matrix_.outerIndexPtr()[c + 1];
    return static_cast<int>(std::lower_bound(begin, end, r) - matrix_.innerIndexPtr());
  };
  diagonal_slot_.assign(n * 6, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const int r0 = first_row_[i];
    for (int r = 0, k = 0; r < 3 && r0 >= 0; ++r) {
      for (int c = 0; c <= r; ++c, ++k) {
        diagonal_slot_[i * 6 + static_cast<std::size_t>(k)] = slot(r0 + r, r0 + c);
      }
    }
  }
  coupling_slot_.assign(pairs.size() * 9, -1);
  coupling_transposed_.assign(pairs.size(), 0);
  coupling_column_.assign(pairs.size(), -1);
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const int ra = row(pairs[p].first);
    const int rb = row(pairs[p].second);
    if (ra < 0 || rb < 0 || ra == rb) {
      continue;
    }
    coupling_transposed_[p] = ra < rb ? 1 : 0;
    coupling_column_[p] = std::min(ra, rb);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        coupling_slot_[p * 9 + static_cast<std::size_t>(3 * r + c)] =
            slot(std::max(ra, rb) + r, std::min(ra, rb) + c);
      }
    }
  }
}

void PointBlockMatrix::clear() {
  std::fill(matrix_.valuePtr(), matrix_.valuePtr() + matrix_.nonZeros(), 0.0);
}

void PointBlockMatrix::add_diagonal(int point, const Mat3& block) {
  const auto base = static_cast<std::size_t>(point) * 6;
  if (diagonal_slot_[base] < 0) {
    return;
  }
  double* values = matrix_.valuePtr();
  for (int r = 0, k = 0; r < 3; ++r) {
    for (int c = 0; c <= r; ++c, ++k) {
      values[diagonal_slot_[base + static_cast<std::size_t>(k)]] += block(r, c);
    }
  }
}

void PointBlockMatrix::add_coupling(std::size_t pair, const Mat3& block) {
  const std::size_t base = pair * 9;
  if (coupling_slot_[base] < 0) {
    return;
  }
  double* values = matrix_.valuePtr();
  const bool transposed = coupling_transposed_[pair] != 0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      values[coupling_slot_[base + static_cast<std::size_t>(3 * r + c)]] +=
          transposed ? block(c, r) : block(r, c);
    }
  }
}

void PointBlockMatrix::damp_diagonal(double relative, double absolute) {
  double* values = matrix_.valuePtr();
  for (std::size_t i = 0; i < first_row_.size(); ++i) {
    if (diagonal_slot_[i * 6] < 0) {
      continue;
    }
    for (int r = 0; r < 3; ++r) {
      // (r, r) in the packed lower block: slots 0, 2, 5
      double& diagonal = values[diagonal_slot_[i * 6 + static_cast<std::size_t>(r * (r + 3) / 2)]];
      diagonal += relative * diagonal + absolute;
    }
  }
}

}  // namespace incise::planning
