#pragma once
// What the coarse levels share, as pure functions: greedy aggregation of a graph's nodes, a
// node's rigid modes orthonormalised over what it spans, a dropped mode's diagonal entry
// filled, and a counting sort by key. Used by the
// aggregates of vertices (aggregation_coarse_space.cpp) and by the levels of groups above them
// (coarse_cycle.cpp).

#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <utility>
#include <vector>

namespace incise::coarse {

/// Rigid modes per node: three translations (m), three rotations (rad) about its centre.
constexpr int kModes = 6;
using Modes = Eigen::Matrix<double, kModes, 1>;            ///< a node's motion in its modes
using ModeMatrix = Eigen::Matrix<double, kModes, kModes>;  ///< one 6x6 block of a coarse matrix

/// Orthonormal modes of a span with Gram matrix `gram` (raw coordinates): W with
/// W^T gram W = I on the kept modes and zero columns for the dropped ones, and its
/// pseudo-inverse. Scaled to unit diagonal first, so metres and radians compare; modes below
/// 1e-6 of the largest eigenvalue are dropped (a rotation the members cannot carry).
struct OrthonormalModes {
  ModeMatrix raw_from_modes = ModeMatrix::Zero();
  ModeMatrix modes_from_raw = ModeMatrix::Zero();
  unsigned dropped = 0;  ///< bit k for mode k
};
[[nodiscard]] OrthonormalModes orthonormal_modes(const ModeMatrix& gram);

/// A coarse diagonal block's dropped modes get a diagonal entry of the kept ones' mean
/// (their rows are zero: the block stays positive definite and the mode's correction zero).
void fill_dropped(ModeMatrix& block, unsigned dropped);

/// first[k] .. first[k + 1]: where the entries with key k (0 <= k < keys) start and end once
/// sorted by key.
void key_offsets(std::span<const int> key, std::size_t keys, std::vector<std::size_t>& first);

/// The indices of `key` grouped by key (a counting sort): key k's at items[first[k] ..
/// first[k + 1]), in increasing order.
void group_by_key(std::span<const int> key, std::size_t keys, std::vector<std::size_t>& first,
                  std::vector<int>& items);

/// A weighted graph in compressed rows (no self loops).
struct Graph {
  std::vector<std::size_t> first{0};
  std::vector<int> node;
  std::vector<double> weight;
  [[nodiscard]] std::size_t size() const { return first.size() - 1; }
};

/// Greedy aggregation (Vanek, Mandel and Brezina 1996) of the eligible nodes: a node whose
/// eligible neighbours are all unclaimed founds an aggregate with them (about one ring, spread
/// without overlap); the rest join the founded aggregate they are most strongly tied to (so
/// aggregates do not creep); nodes with none beside them group with their unclaimed
/// neighbours. Returns each node's aggregate (-1 where not eligible) and the count.
[[nodiscard]] std::pair<std::vector<int>, int> greedy_aggregates(const Graph& graph,
                                                                 const std::vector<char>& eligible);

}  // namespace incise::coarse
