#pragma once
// A symmetric matrix of 3x3 blocks over some of a model's points, for the Newton-type solves of
// planning (the equilibrium's rest lengths, the prediction's positions). Its pattern (a block
// per point in the system and per given pair of them) is built once; each iteration clears the
// values and adds blocks in place through precomputed slots, with no triplet sorting. The lower
// triangle is stored, as DirectFactorization reads it.

#include <span>
#include <utility>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/solve/direct_factorization.hpp"

namespace incise::planning {

class PointBlockMatrix {
 public:
  /// `first_row[i]`: the first of point i's three rows (a multiple of 3 below `rows`, each
  /// point its own), or -1 when i is not in the system.
  /// `pairs`: the point pairs that may couple (pairs with a point outside are ignored).
  PointBlockMatrix(std::vector<int> first_row, int rows,
                   std::span<const std::pair<int, int>> pairs);

  void clear();
  /// Adds `block` to point i's diagonal block (nothing when i is not in the system).
  void add_diagonal(int point, const Mat3& block);
  /// Adds `block` at (a, b) of pair `pair` = (a, b), and its transpose at (b, a).
  void add_coupling(std::size_t pair, const Mat3& block);
  /// Each diagonal entry d becomes d (1 + relative) + absolute.
  void damp_diagonal(double relative, double absolute);

  [[nodiscard]] const DirectFactorization::SparseMatrix& matrix() const { return matrix_; }
  [[nodiscard]] int row(int point) const { return first_row_[static_cast<std::size_t>(point)]; }
  /// The first of the three columns that hold pair `pair`'s stored block (the smaller of its
  /// points' first rows), -1 where it is not in the system; a point's diagonal block is in
  /// columns row(point) to row(point) + 2. Adds to blocks in disjoint column ranges touch
  /// disjoint values: they may run on separate threads.
  [[nodiscard]] int coupling_column(std::size_t pair) const { return coupling_column_[pair]; }
  [[nodiscard]] int rows() const { return static_cast<int>(matrix_.rows()); }

 private:
  std::vector<int> first_row_;
  DirectFactorization::SparseMatrix matrix_;
  std::vector<int> diagonal_slot_;  ///< per point: its packed lower block (6), or -1
  std::vector<int> coupling_slot_;  ///< per pair: the 3x3 block below the diagonal (9), or -1
  std::vector<char> coupling_transposed_;  ///< per pair: the stored block is (b, a)
  std::vector<int> coupling_column_;       ///< per pair: see coupling_column()
};

}  // namespace incise::planning
