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

  /// Where a block's values lie: its (0, 0) (`first`, -1 when the block is not in the system)
  /// and how far on its next column starts (`step`; negative: the block given is added
  /// transposed). Looked up once for an element's blocks, then added for each assembly
  /// without the lookups (the planning Hessian's prisms: 21 blocks each).
  struct Target {
    int first = -1;
    int step = 0;
  };
  [[nodiscard]] Target diagonal_target(int point) const;
  /// The target of a block at (a, b) of pair `pair` = (a, b) (`as_given`), or at (b, a).
  [[nodiscard]] Target coupling_target(std::size_t pair, bool as_given) const;
  /// Adds a symmetric `block` at a diagonal_target() (its lower part).
  void add_diagonal(const Target& target, const Mat3& block);
  /// Adds `block` at a coupling_target() and its transpose at the mirrored place.
  void add_coupling(const Target& target, const Mat3& block);
  /// The first value of column `column` (0 to rows()): a target whose `first` lies in
  /// [value_start(low), value_start(high)) is in columns [low, high) (whole points' columns).
  /// Adds to blocks in disjoint column ranges touch disjoint values: they may run on separate
  /// threads.
  [[nodiscard]] int value_start(int column) const { return matrix_.outerIndexPtr()[column]; }
  /// Each diagonal entry d becomes d (1 + relative) + absolute.
  void damp_diagonal(double relative, double absolute);

  [[nodiscard]] const DirectFactorization::SparseMatrix& matrix() const { return matrix_; }
  [[nodiscard]] int row(int point) const { return first_row_[static_cast<std::size_t>(point)]; }
  [[nodiscard]] int rows() const { return static_cast<int>(matrix_.rows()); }

 private:
  std::vector<int> first_row_;
  DirectFactorization::SparseMatrix matrix_;
  // A block's values lie in its three columns, rows in order: (r, c) at first + r + offset(c),
  // offset = 0, 2 + 3 d, 3 + 6 d = 0, step, 2 step - 1, d the coupling blocks below the
  // diagonal in its block column (the diagonal block stores r >= c). A slot and a count a
  // block, not nine slots (36 bytes read at random per add).
  std::vector<int> diagonal_first_;        ///< per point: its diagonal block's (0, 0), or -1
  std::vector<int> coupling_first_;        ///< per pair: its stored block's (0, 0), or -1
  std::vector<int> below_diagonal_;        ///< per block column: d, the coupling blocks below
  std::vector<char> coupling_transposed_;  ///< per pair: the stored block is (b, a)
  std::vector<int> coupling_column_;       ///< per pair: the first column of its stored block
};

}  // namespace incise::planning
