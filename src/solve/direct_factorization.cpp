#include "incise/solve/direct_factorization.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/solve/linear_solvers.hpp"

#ifdef INCISE_HAVE_CHOLMOD
#include <dlfcn.h>

#include <Eigen/CholmodSupport>
#include <cstdlib>
#include <mutex>

#include "single_precision_supernodes.hpp"
#endif

namespace incise {

struct DirectFactorization::Backends {
#ifdef INCISE_HAVE_CHOLMOD
  /// Eigen's CHOLMOD supernodal Cholesky, with its factor readable (for the single-precision
  /// copy).
  class CholmodLLT : public Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> {
   public:
    [[nodiscard]] const cholmod_factor* factor() const { return m_cholmodFactor; }
  };
  CholmodLLT cholmod;
  bool cholmod_analyzed = false;
  Cost cholmod_cost;  ///< from the analysis
  SinglePrecisionSupernodes single;
  bool single_current = false;  ///< `single` copies the last factor
  bool double_current = false;  ///< `cholmod` holds the last factor (not single precision only)
#endif
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt;
  bool ldlt_analyzed = false;
  bool ldlt_factorized = false;
  bool using_cholmod = false;
  /// The pattern the analyses were made for (column starts, row indices): a matrix with
  /// another one is analysed again, so that callers of one pattern can share the analysis and
  /// one that changes it cannot mistake it (a comparison, against an analysis 100x its cost).
  std::vector<int> analysed_starts;
  std::vector<int> analysed_rows;
  int analyses = 0;  ///< symbolic analyses made, by either backend

  /// Drops the analyses and the pattern they were made for.
  void forget_analyses() {
#ifdef INCISE_HAVE_CHOLMOD
    cholmod_analyzed = false;
#endif
    ldlt_analyzed = false;
    ldlt_factorized = false;
    analysed_starts.clear();
    analysed_rows.clear();
  }

  /// Drops the analyses when `matrix` has another pattern than the one they were made for.
  void follow_pattern(const SparseMatrix& matrix) {
    const auto columns = static_cast<std::size_t>(matrix.outerSize());
    const auto entries = static_cast<std::size_t>(matrix.nonZeros());
    const bool same =
        matrix.isCompressed() && analysed_starts.size() == columns + 1 &&
        analysed_rows.size() == entries &&
        std::equal(analysed_starts.begin(), analysed_starts.end(), matrix.outerIndexPtr()) &&
        std::equal(analysed_rows.begin(), analysed_rows.end(), matrix.innerIndexPtr());
    if (same) {
      return;
    }
    forget_analyses();
    if (matrix.isCompressed()) {
      analysed_starts.assign(matrix.outerIndexPtr(), matrix.outerIndexPtr() + columns + 1);
      analysed_rows.assign(matrix.innerIndexPtr(), matrix.innerIndexPtr() + entries);
    }
  }

#ifdef INCISE_HAVE_CHOLMOD
  /// CHOLMOD's supernodal Cholesky (the pattern analysed once); false when not positive definite.
  bool factorize_cholmod(const SparseMatrix& matrix) {
    analyse_cholmod(matrix);
    cholmod.factorize(matrix);
    single_current = false;
    using_cholmod = cholmod.info() == Eigen::Success;
    double_current = using_cholmod;
    return using_cholmod;
  }
  /// CHOLMOD's analysis of the matrix's pattern, once per pattern.
  void analyse_cholmod(const SparseMatrix& matrix) {
    if (!cholmod_analyzed) {
      single.forget_pattern();  // the analysis makes a new factor, perhaps at the same address
      cholmod.analyzePattern(matrix);
      ++analyses;
      cholmod_analyzed = true;
      cholmod_cost = {cholmod.cholmod().lnz, cholmod.cholmod().fl};
    }
  }
#endif
  /// LDL^T (the pattern analysed once): takes symmetric indefinite matrices whose pivots stay
  /// nonzero.
  bool factorize_ldlt(const SparseMatrix& matrix) {
    using_cholmod = false;
    if (!ldlt_analyzed) {
      ldlt.analyzePattern(matrix);
      ++analyses;
      ldlt_analyzed = true;
    }
    ldlt.factorize(matrix);
    ldlt_factorized = ldlt.info() == Eigen::Success;
    return ldlt_factorized;
  }
};

#ifdef INCISE_HAVE_CHOLMOD
namespace {

/// OpenBLAS (behind CHOLMOD's supernodal updates) starts a thread per core that spins while
/// waiting: on a loaded 2-core machine beside incise's own TBB workers a factorisation took 10x
/// longer (system time) than on one thread, and never less than 0.95x of it unloaded. One thread
/// unless the user chose otherwise through OPENBLAS_NUM_THREADS; looked up at run time because
/// the BLAS behind CHOLMOD may be another one (Debian's alternatives).
void use_one_blas_thread_unless_chosen() {
  static std::once_flag once;  // a process-wide library setting, made once
  std::call_once(once, [] {
    if (std::getenv("OPENBLAS_NUM_THREADS") != nullptr) {
      return;
    }
    using SetThreads = void (*)(int);
    if (void* symbol = dlsym(RTLD_DEFAULT, "openblas_set_num_threads")) {
      reinterpret_cast<SetThreads>(symbol)(1);
    }
  });
}

}  // namespace
#endif

DirectFactorization::DirectFactorization() : backends_(std::make_unique<Backends>()) {
#ifdef INCISE_HAVE_CHOLMOD
  use_one_blas_thread_unless_chosen();
  // A matrix that is not positive definite is an answer here (the caller falls back), not a
  // warning for the terminal.
  backends_->cholmod.cholmod().print = 0;
#endif
}
DirectFactorization::~DirectFactorization() = default;

bool DirectFactorization::factorize(const SparseMatrix& matrix) {
  backends_->follow_pattern(matrix);
#ifdef INCISE_HAVE_CHOLMOD
  if (backends_->factorize_cholmod(matrix)) {
    return true;
  }
#endif
  // Not positive definite (or no CHOLMOD): LDL^T.
  return backends_->factorize_ldlt(matrix);
}

bool DirectFactorization::factorize_positive_definite(const SparseMatrix& matrix) {
  backends_->follow_pattern(matrix);
#ifdef INCISE_HAVE_CHOLMOD
  return backends_->factorize_cholmod(matrix);
#else
  return backends_->factorize_ldlt(matrix) && backends_->ldlt.vectorD().minCoeff() > 0.0;
#endif
}

bool DirectFactorization::factorize_single_precision(const SparseMatrix& matrix) {
  backends_->follow_pattern(matrix);
#ifdef INCISE_HAVE_CHOLMOD
  Backends& b = *backends_;
  b.analyse_cholmod(matrix);
  b.double_current = false;
  b.single_current =
      b.cholmod.factor() != nullptr && b.single.factorize(*b.cholmod.factor(), matrix);
  b.using_cholmod = b.single_current;
  return b.single_current;
#else
  return false;
#endif
}

bool DirectFactorization::factorize_preconditioner(const SparseMatrix& matrix,
                                                   bool positive_definite_only) {
  if (factorize_single_precision(matrix)) {
    return true;
  }
  return positive_definite_only ? factorize_positive_definite(matrix) : factorize(matrix);
}

int DirectFactorization::analyses() const {
  return backends_->analyses;
}

Eigen::VectorXd DirectFactorization::solve(const Eigen::VectorXd& rhs) const {
#ifdef INCISE_HAVE_CHOLMOD
  if (backends_->using_cholmod) {
    INCISE_ASSERT(backends_->double_current,
                  "DirectFactorization::solve after a single-precision factorisation");
    return backends_->cholmod.solve(rhs);
  }
#endif
  return backends_->ldlt.solve(rhs);
}

Eigen::VectorXd DirectFactorization::solve_single_precision(const Eigen::VectorXd& rhs) {
#ifdef INCISE_HAVE_CHOLMOD
  Backends& b = *backends_;
  if (b.using_cholmod) {
    if (!b.single_current) {
      b.single.copy(*b.cholmod.factor());
      b.single_current = true;
    }
    if (b.single.valid()) {
      return b.single.solve(rhs);
    }
  }
#endif
  return solve(rhs);
}

DirectFactorization::Cost DirectFactorization::cost() const {
#ifdef INCISE_HAVE_CHOLMOD
  if (backends_->using_cholmod) {
    return backends_->cholmod_cost;
  }
#endif
  if (!backends_->ldlt_factorized) {
    return {};
  }
  const auto l = backends_->ldlt.matrixL();
  const SparseMatrix& factor = l.nestedExpression();
  Cost cost;
  cost.nonzeros = static_cast<double>(factor.nonZeros());
  for (Eigen::Index c = 0; c < factor.outerSize(); ++c) {
    const auto column =
        static_cast<double>(factor.outerIndexPtr()[c + 1] - factor.outerIndexPtr()[c]);
    cost.flops += column * column;
  }
  return cost;
}

std::string DirectFactorization::backend() const {
  if (!backends_->using_cholmod) {
    return "simplicial-ldlt";
  }
#ifdef INCISE_HAVE_CHOLMOD
  if (!backends_->double_current) {
    return "single-precision-supernodal";
  }
#endif
  return "cholmod-supernodal";
}

std::size_t auto_direct_limit() {
  return has_cholmod_backend() ? 150000 : 15000;
}

bool has_cholmod_backend() {
#ifdef INCISE_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

}  // namespace incise
