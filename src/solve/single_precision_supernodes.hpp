#pragma once
// A single-precision copy of CHOLMOD's supernodal Cholesky factor, and the two triangular
// sweeps with it, over independent subtrees of the supernodes on worker threads. Solves with a
// large factor are bound by reading it from memory (each solve reads every nonzero twice): in
// floats that is half the bytes, for a preconditioner whose answer is wanted to a few digits,
// not sixteen; and CHOLMOD's own solve runs on one core. Written here because CHOLMOD 3
// (Debian 12's SuiteSparse 5.12) factorises and solves in double precision only.

#include <cholmod.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cstddef>
#include <vector>

namespace incise {

/// A supernodal factor's integer arrays (CHOLMOD's, read in place).
struct SupernodeView {
  const int* super;  ///< supernode s holds columns super[s] to super[s + 1] - 1
  const int* pi;     ///< its rows are rows[pi[s]] to rows[pi[s + 1] - 1], its columns first
  const int* px;     ///< its dense block starts at values[px[s]]
  const int* rows;
  int count;
  explicit SupernodeView(const cholmod_factor& l)
      : super(static_cast<const int*>(l.super)),
        pi(static_cast<const int*>(l.pi)),
        px(static_cast<const int*>(l.px)),
        rows(static_cast<const int*>(l.s)),
        count(static_cast<int>(l.nsuper)) {}
  [[nodiscard]] int columns(int s) const { return super[s + 1] - super[s]; }
  [[nodiscard]] int height(int s) const { return pi[s + 1] - pi[s]; }
  /// Supernode s's dense columns in `values` (height x columns, column-major).
  using Block = Eigen::Map<const Eigen::MatrixXf, 0, Eigen::OuterStride<>>;
  [[nodiscard]] Block block(int s, const std::vector<float>& values) const {
    return {values.data() + px[s], height(s), columns(s), Eigen::OuterStride<>(height(s))};
  }
  /// Its rows below its diagonal block.
  [[nodiscard]] const int* rows_below(int s) const { return rows + pi[s] + columns(s); }
  /// The supernode that holds each of the `n` columns.
  [[nodiscard]] std::vector<int> supernode_of_columns(std::size_t n) const {
    std::vector<int> of_column(n);
    for (int s = 0; s < count; ++s) {
      std::fill(of_column.begin() + super[s], of_column.begin() + super[s + 1], s);
    }
    return of_column;
  }
};

class SinglePrecisionSupernodes {
 public:
  /// Copies the values of `factor` (supernodal LL', int indices, real double, every value
  /// within a float's range; else valid() is false). The factor's integer arrays are read in
  /// place: it must outlive this copy and keep its pattern until forget_pattern().
  void copy(const cholmod_factor& factor);
  [[nodiscard]] bool valid() const { return factor_ != nullptr; }
  /// Factorises `lower` (a symmetric matrix's lower triangle, of the pattern `symbolic` was
  /// analysed for: CHOLMOD's symbolic supernodal factor, which must outlive this one) in
  /// single precision, into this factor: false when it is not positive definite in floats (a
  /// pivot not above zero or not finite), and then valid() is false. The subtrees of the
  /// sweeps are factorised side by side, each supernode pulling its descendants' updates in a
  /// fixed order: the same factor, bit for bit, on any number of threads.
  bool factorize(const cholmod_factor& symbolic,
                 const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& lower);
  /// The factor is analysed again (its pattern may differ): the next copy splits it anew.
  void forget_pattern() {
    factor_ = nullptr;
    split_made_ = false;
    plan_made_ = false;
  }
  /// x with P A P^T = L L^T, A x = b (CHOLMOD's solve, to about 1e-7 of its size times the
  /// matrix's condition number). The same answer, bit for bit, for any number of threads.
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& b);

 private:
  /// Splits the supernodes into subtrees that do not touch each other's columns, and the top
  /// of the tree above them (pattern only: made once per pattern).
  void split(const cholmod_factor& factor);
  /// Where the factorisation takes its numbers from (pattern only: made once per pattern):
  /// each matrix entry's place in its permuted column, and each supernode's updates.
  void plan_factorization(const cholmod_factor& symbolic,
                          const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& lower);
  /// Supernode s's columns: the matrix's entries, the updates of the supernodes below it, its
  /// diagonal block's Cholesky factor and the rows below solved against it. False when the
  /// block is not positive definite. `map` (a row per column of the matrix) and `product` are
  /// the caller's room.
  bool factorize_supernode(int s, std::vector<int>& map, std::vector<float>& product);
  /// The same for a supernode of the top (few, wide and tall), its work split into fixed
  /// chunks of rows on worker threads.
  bool factorize_wide_supernode(int s, std::vector<int>& map);
  /// Supernode s's block zeroed, the matrix's entries added, `map` set to its rows' places.
  void assemble_supernode(int s, std::vector<int>& map);
  /// The updates of the supernodes below s to its block's rows [lower, upper), in order.
  void subtract_updates(int s, const std::vector<int>& map, int lower, int upper,
                        std::vector<float>& product);
  /// One supernode of L y = P b; its updates to the top's columns go to `top_sums` (null:
  /// straight into the right-hand side). `below`: room for its rows below its block.
  void forward(int supernode, float* top_sums, float* below);
  /// One supernode of L^T z = y.
  void backward(int supernode, float* below);

  const cholmod_factor* factor_ = nullptr;
  std::vector<float> values_;  ///< the supernodes' dense columns, as CHOLMOD stores them
  Eigen::VectorXf work_;       ///< the permuted right-hand side, swept in place
  // The split, from the factor's pattern:
  bool split_made_ = false;                 ///< for the factor's current pattern
  std::vector<std::vector<int>> subtrees_;  ///< each subtree's supernodes, children first
  std::vector<int> top_;                    ///< the others, children first
  std::vector<int> top_position_;  ///< per column: its place among the top's columns, or -1
  int top_columns_ = 0;
  std::vector<float> top_sums_;  ///< per subtree, its updates to the top's columns
  std::vector<float> below_;     ///< per subtree, room for a supernode's rows below its block
  // The factorisation's plan, from the pattern:
  bool plan_made_ = false;
  std::vector<int> permuted_start_;  ///< P A P^T's lower columns: where each starts
  std::vector<int> permuted_row_;    ///< each entry's row
  std::vector<int> permuted_from_;   ///< each entry's index among the matrix's values
  /// The updates to supernode s: update_first_[s] to update_first_[s + 1] - 1 in update_,
  /// each a descendant and the range of its rows below its block that fall in s's columns.
  struct Update {
    int descendant;
    int first;  ///< among its rows (counted from its first), the first in s's columns
    int last;   ///< one past the last
  };
  std::vector<int> update_first_;
  std::vector<Update> update_;
  std::vector<float> permuted_values_;        ///< P A P^T's lower values, in floats
  std::vector<std::vector<int>> maps_;        ///< per subtree, then the top: room for a row map
  std::vector<std::vector<float>> products_;  ///< per subtree: room for an update
  std::vector<std::vector<float>> chunk_products_;  ///< per chunk of a top supernode's rows
  std::vector<char> subtree_failed_;                ///< per subtree: a pivot not above zero
};

}  // namespace incise
