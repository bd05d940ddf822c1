#include "rigid_block_maths.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace incise::coarse {

std::pair<std::vector<int>, int> greedy_aggregates(const Graph& graph,
                                                   const std::vector<char>& eligible) {
  const std::size_t n = graph.size();
  std::vector<int> aggregate(n, -1);
  int count = 0;
  auto neighbours = [&](std::size_t i) {
    return std::span<const int>(graph.node)
        .subspan(graph.first[i], graph.first[i + 1] - graph.first[i]);
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (eligible[i] == 0 || aggregate[i] >= 0) {
      continue;
    }
    const auto around = neighbours(i);
    if (!std::all_of(around.begin(), around.end(), [&](int j) {
          return eligible[static_cast<std::size_t>(j)] == 0 ||
                 aggregate[static_cast<std::size_t>(j)] < 0;
        })) {
      continue;
    }
    aggregate[i] = count;
    for (const int j : around) {
      if (eligible[static_cast<std::size_t>(j)] != 0) {
        aggregate[static_cast<std::size_t>(j)] = count;
      }
    }
    ++count;
  }
  const std::vector<int> founded = aggregate;
  for (std::size_t i = 0; i < n; ++i) {
    if (eligible[i] == 0 || founded[i] >= 0) {
      continue;
    }
    double strongest = -1.0;
    for (std::size_t k = graph.first[i]; k < graph.first[i + 1]; ++k) {
      const int other = founded[static_cast<std::size_t>(graph.node[k])];
      if (other >= 0 && graph.weight[k] > strongest) {
        strongest = graph.weight[k];
        aggregate[i] = other;
      }
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (eligible[i] == 0 || aggregate[i] >= 0) {
      continue;
    }
    aggregate[i] = count;
    for (const int j : neighbours(i)) {
      if (eligible[static_cast<std::size_t>(j)] != 0 &&
          aggregate[static_cast<std::size_t>(j)] < 0) {
        aggregate[static_cast<std::size_t>(j)] = count;
      }
    }
    ++count;
  }
  return {std::move(aggregate), count};
}

OrthonormalModes orthonormal_modes(const ModeMatrix& gram) {
  constexpr double kDropBelow = 1e-6;
  Modes scale;
  for (int k = 0; k < kModes; ++k) {
    scale[k] = gram(k, k) > 0.0 ? 1.0 / std::sqrt(gram(k, k)) : 0.0;
  }
  const ModeMatrix scaled = scale.asDiagonal() * gram * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<ModeMatrix> eigen(scaled);
  const double largest = eigen.eigenvalues().maxCoeff();
  OrthonormalModes result;
  for (int k = 0; k < kModes; ++k) {
    const double lambda = eigen.eigenvalues()[k];
    if (!(largest > 0.0) || !(lambda > kDropBelow * largest)) {
      result.dropped |= 1U << static_cast<unsigned>(k);
      continue;
    }
    const Modes v = eigen.eigenvectors().col(k);
    result.raw_from_modes.col(k) = scale.asDiagonal() * v / std::sqrt(lambda);
    for (int c = 0; c < kModes; ++c) {
      result.modes_from_raw(k, c) = scale[c] > 0.0 ? std::sqrt(lambda) * v[c] / scale[c] : 0.0;
    }
  }
  return result;
}

void fill_dropped(ModeMatrix& block, unsigned dropped) {
  double kept_sum = 0.0;
  int kept = 0;
  for (int k = 0; k < kModes; ++k) {
    if ((dropped & (1U << static_cast<unsigned>(k))) == 0) {
      kept_sum += block(k, k);
      ++kept;
    }
  }
  const double fill = kept > 0 && kept_sum > 0.0 ? kept_sum / kept : 1.0;
  for (int k = 0; k < kModes; ++k) {
    if ((dropped & (1U << static_cast<unsigned>(k))) != 0) {
      block(k, k) = fill;
    }
  }
}

void key_offsets(std::span<const int> key, std::size_t keys, std::vector<std::size_t>& first) {
  first.assign(keys + 1, 0);
  for (const int k : key) {
    ++first[static_cast<std::size_t>(k) + 1];
  }
  for (std::size_t k = 0; k < keys; ++k) {
    first[k + 1] += first[k];
  }
}

void group_by_key(std::span<const int> key, std::size_t keys, std::vector<std::size_t>& first,
                  std::vector<int>& items) {
  key_offsets(key, keys, first);
  items.resize(key.size());
  std::vector<std::size_t> next(first.begin(), first.end() - 1);
  for (std::size_t i = 0; i < key.size(); ++i) {
    items[next[static_cast<std::size_t>(key[i])]++] = static_cast<int>(i);
  }
}

}  // namespace incise::coarse
