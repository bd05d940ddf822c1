#pragma once
// Sparse direct factorisation of the free rows of a system matrix. CHOLMOD's supernodal
// Cholesky (SuiteSparse, through Eigen's support module) when incise is built with it: its
// dense supernode blocks run through BLAS and are many times faster than a simplicial
// factorisation on the fill-heavy matrices of 3-D meshes. Eigen's SimplicialLDLT otherwise,
// and as the fallback for matrices that are symmetric but not positive definite (a
// mass-spring tangent with compressed springs). Used by LinearizedSystemSolver and by the
// planning module's equilibrium initialisation.

#include <Eigen/SparseCore>
#include <memory>
#include <string>

namespace incise {

/// A sparse symmetric factorisation: CHOLMOD's supernodal Cholesky, else Eigen's simplicial
/// LDL^T for indefinite matrices; the symbolic analysis is kept while the pattern is the same
/// (compared at each factorisation: a matrix of another pattern is analysed again).
class DirectFactorization {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;  ///< what it reads
  DirectFactorization();
  ~DirectFactorization();
  DirectFactorization(const DirectFactorization&) = delete;
  DirectFactorization& operator=(const DirectFactorization&) = delete;

  /// Factorises the matrix (lower triangle read); false when neither backend can.
  [[nodiscard]] bool factorize(const SparseMatrix& matrix);
  /// Factorises the matrix only if it is positive definite (no indefinite fallback): false
  /// otherwise, quickly, so that a caller can fall back to a convexified matrix.
  [[nodiscard]] bool factorize_positive_definite(const SparseMatrix& matrix);
  /// Factorises the matrix (lower triangle read) in single precision, for
  /// solve_single_precision() only (solve() is then not available): false when it is not
  /// positive definite in floats, or without CHOLMOD (whose analysis it uses). Half the bytes
  /// and about half the time of factorize() on one core, and its independent subtrees on
  /// TBB's workers; the same factor on any number of threads.
  [[nodiscard]] bool factorize_single_precision(const SparseMatrix& matrix);
  /// A factor for solve_single_precision(): factorize_single_precision() where floats suffice,
  /// else factorize_positive_definite() (`positive_definite_only`) or factorize(), in double.
  [[nodiscard]] bool factorize_preconditioner(const SparseMatrix& matrix,
                                              bool positive_definite_only);
  /// The solution of the last factorised matrix for `rhs`.
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& rhs) const;
  /// The same solution from a single-precision copy of CHOLMOD's factor (made on the first
  /// call after each factorisation): half the bytes read of solve(), which a large factor's
  /// solves are bound by, for about 1e-7 of relative precision times the matrix's condition
  /// number: for preconditioning. solve() itself where the factor is not CHOLMOD's. Its
  /// sweeps run on TBB's workers; one caller at a time (it keeps the copy and a work vector).
  [[nodiscard]] Eigen::VectorXd solve_single_precision(const Eigen::VectorXd& rhs);
  /// "cholmod-supernodal", "single-precision-supernodal" (factorize_single_precision) or
  /// "simplicial-ldlt": which backend factorised last.
  [[nodiscard]] std::string backend() const;

  /// The last factor's size: its nonzeros and the floating-point operations that made it
  /// (CHOLMOD's count from its analysis; for LDL^T, the sum of its columns' squared lengths).
  /// What a caller weighs a new factorisation against more solves with this factor by.
  struct Cost {
    double nonzeros = 0.0;  ///< in the factor
    double flops = 0.0;     ///< to make it
  };
  [[nodiscard]] Cost cost() const;  ///< the last factor's
  /// Symbolic analyses (orderings and supernode structure) made so far: one per pattern
  /// met, and one more for each return to an earlier one.
  [[nodiscard]] int analyses() const;

 private:
  struct Backends;
  std::unique_ptr<Backends> backends_;
};

}  // namespace incise
