#pragma once
// A single-precision copy of CHOLMOD's supernodal Cholesky factor, and the two triangular
// sweeps with it, over independent subtrees of the supernodes on worker threads. Solves with a
// large factor are bound by reading it from memory (each solve reads every nonzero twice): in
// floats that is half the bytes, for a preconditioner whose answer is wanted to a few digits,
// not sixteen; and CHOLMOD's own solve runs on one core. Written here because CHOLMOD 3
// (Debian 12's SuiteSparse 5.12) factorises and solves in double precision only.

#include <cholmod.h>

#include <Eigen/Core>
#include <vector>

namespace incise {

class SinglePrecisionSupernodes {
 public:
  /// Copies the values of `factor` (supernodal LL', int indices, real double, every value
  /// within a float's range; else valid() is false). The factor's integer arrays are read in
  /// place: it must outlive this copy and keep its pattern until forget_pattern().
  void copy(const cholmod_factor& factor);
  [[nodiscard]] bool valid() const { return factor_ != nullptr; }
  /// The factor is analysed again (its pattern may differ): the next copy splits it anew.
  void forget_pattern() {
    factor_ = nullptr;
    split_made_ = false;
  }
  /// x with P A P^T = L L^T, A x = b (CHOLMOD's solve, to about 1e-7 of its size times the
  /// matrix's condition number). The same answer, bit for bit, for any number of threads.
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& b);

 private:
  /// Splits the supernodes into subtrees that do not touch each other's columns, and the top
  /// of the tree above them (pattern only: made once per pattern).
  void split(const cholmod_factor& factor);
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
};

}  // namespace incise
