// DirectFactorization's single-precision solve: CHOLMOD's factor copied to floats and swept
// over independent subtrees on worker threads. It must give CHOLMOD's answer to single
// precision, the same bits for any thread count, and follow each new factorisation.

#include "incise/solve/direct_factorization.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/SparseCore>
#include <random>
#include <vector>

namespace incise {
namespace {

using SparseMatrix = DirectFactorization::SparseMatrix;

/// The lower triangle of an elasticity-like matrix on an n^3 grid: the 7-point Laplacian times
/// a coupling block between the three unknowns per point, plus a small shift (condition about
/// 1e4, like a soft body's stiffness with its mass).
SparseMatrix grid_matrix(int n, double scale, bool diagonals = false) {
  Eigen::Matrix3d block;
  block << 2.0, 0.5, 0.0, 0.5, 2.0, 0.3, 0.0, 0.3, 1.0;
  const auto index = [n](int i, int j, int k) { return (i * n + j) * n + k; };
  std::vector<Eigen::Triplet<double>> entries;
  const auto add = [&](int a, int b, double weight) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        const int row = 3 * a + r;
        const int column = 3 * b + c;
        if (row >= column) {
          entries.emplace_back(row, column, scale * weight * block(r, c));
        }
      }
    }
  };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int k = 0; k < n; ++k) {
        const int p = index(i, j, k);
        add(p, p, 6.001);
        if (i > 0)
          add(p, index(i - 1, j, k), -1.0);
        if (j > 0)
          add(p, index(i, j - 1, k), -1.0);
        if (k > 0)
          add(p, index(i, j, k - 1), -1.0);
        if (diagonals && i > 0 && j > 0)
          add(p, index(i - 1, j - 1, k), -0.001);
      }
    }
  }
  SparseMatrix matrix(3 * n * n * n, 3 * n * n * n);
  matrix.setFromTriplets(entries.begin(), entries.end());
  return matrix;
}

/// Entries uniform in [-1, 1], from `seed`.
Eigen::VectorXd random_vector(Eigen::Index size, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  Eigen::VectorXd v(size);
  for (Eigen::Index i = 0; i < size; ++i) {
    v[i] = entry(random);
  }
  return v;
}

TEST(DirectFactorization, SinglePrecisionSolvesAgreeWithTheDoubleOnesOnAnyThreadCount) {
  if (!has_cholmod_backend()) {
    GTEST_SKIP() << "built without CHOLMOD: solve_single_precision is solve";
  }
  const SparseMatrix matrix = grid_matrix(18, 1.0);  // 17,496 unknowns
  DirectFactorization factor;
  ASSERT_TRUE(factor.factorize_positive_definite(matrix));
  const Eigen::VectorXd b = random_vector(matrix.rows(), 7);
  const Eigen::VectorXd exact = factor.solve(b);
  const auto a = matrix.selfadjointView<Eigen::Lower>();
  ASSERT_LT((a * exact - b).norm(), 1e-10 * b.norm());

  // Factorised and solved under each thread count: the same answer, bit for bit.
  std::vector<Eigen::VectorXd> answers;
  for (const int threads : {1, 2, 5}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(threads));
    DirectFactorization fresh;
    ASSERT_TRUE(fresh.factorize_positive_definite(matrix));
    answers.push_back(fresh.solve_single_precision(b));
    EXPECT_EQ(fresh.solve_single_precision(b), answers.back()) << threads << " threads";
  }
  const Eigen::VectorXd& single = answers.front();
  EXPECT_LT((single - exact).norm(), 1e-5 * exact.norm());
  EXPECT_LT((a * single - b).norm(), 1e-5 * b.norm());
  EXPECT_GT((single - exact).norm(), 0.0);  // floats, not the double solve
  EXPECT_EQ(answers[0], answers[1]);
  EXPECT_EQ(answers[0], answers[2]);

  // A new factorisation on the same pattern: the copy follows it.
  ASSERT_TRUE(factor.factorize_positive_definite(grid_matrix(18, 4.0)));
  const Eigen::VectorXd quarter = factor.solve_single_precision(b);
  EXPECT_LT((4.0 * quarter - exact).norm(), 1e-5 * exact.norm());
}

TEST(DirectFactorization, ASinglePrecisionFactorisationSolvesLikeTheDoubleOneOnAnyThreadCount) {
  if (!has_cholmod_backend()) {
    GTEST_SKIP() << "built without CHOLMOD: no single-precision factorisation";
  }
  const SparseMatrix matrix = grid_matrix(18, 1.0, true);  // 17,496 unknowns
  DirectFactorization reference;
  ASSERT_TRUE(reference.factorize_positive_definite(matrix));
  const Eigen::VectorXd b = random_vector(matrix.rows(), 11);
  const Eigen::VectorXd exact = reference.solve(b);
  const auto a = matrix.selfadjointView<Eigen::Lower>();
  // Factorised in floats under each thread count: the same factor (so the same answer), bit
  // for bit, and the double factor's answer to single precision.
  std::vector<Eigen::VectorXd> answers;
  for (const int threads : {1, 2, 5}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(threads));
    DirectFactorization single;
    ASSERT_TRUE(single.factorize_single_precision(matrix));
    EXPECT_EQ(single.backend(), "single-precision-supernodal");
    answers.push_back(single.solve_single_precision(b));
  }
  EXPECT_EQ(answers[0], answers[1]);
  EXPECT_EQ(answers[0], answers[2]);
  EXPECT_LT((answers[0] - exact).norm(), 1e-5 * exact.norm());
  EXPECT_LT((a * answers[0] - b).norm(), 1e-5 * b.norm());
  EXPECT_GT((answers[0] - exact).norm(), 0.0);  // floats, not the double solve

  // Refactorised on the same pattern (the plan kept), then in double: each solve follows the
  // last factorisation.
  DirectFactorization factor;
  ASSERT_TRUE(factor.factorize_single_precision(matrix));
  ASSERT_TRUE(factor.factorize_single_precision(4.0 * matrix));
  EXPECT_LT((4.0 * factor.solve_single_precision(b) - exact).norm(), 1e-5 * exact.norm());
  ASSERT_TRUE(factor.factorize_positive_definite(2.0 * matrix));
  EXPECT_EQ(factor.backend(), "cholmod-supernodal");
  EXPECT_LT((2.0 * factor.solve(b) - exact).norm(), 1e-10 * exact.norm());
  EXPECT_LT((2.0 * factor.solve_single_precision(b) - exact).norm(), 1e-5 * exact.norm());
  ASSERT_TRUE(factor.factorize_single_precision(matrix));
  EXPECT_LT((factor.solve_single_precision(b) - exact).norm(), 1e-5 * exact.norm());

  // Not positive definite: refused, as in double.
  SparseMatrix indefinite = matrix;
  indefinite.coeffRef(600, 600) = -1.0;
  EXPECT_FALSE(reference.factorize_positive_definite(indefinite));
  EXPECT_FALSE(factor.factorize_single_precision(indefinite));
  // Beyond a float's range: refused, where the double factorisation succeeds.
  EXPECT_FALSE(factor.factorize_single_precision(1e40 * matrix));
  ASSERT_TRUE(factor.factorize_positive_definite(1e40 * matrix));
  EXPECT_LT((1e40 * factor.solve(b) - exact).norm(), 1e-10 * exact.norm());
}

TEST(DirectFactorization, SinglePrecisionSolvesFollowANewPattern) {
  if (!has_cholmod_backend()) {
    GTEST_SKIP() << "built without CHOLMOD: solve_single_precision is solve";
  }
  DirectFactorization factor;
  for (const int n : {10, 12, 9}) {  // each a new pattern, analysed again without being told
    const SparseMatrix matrix = grid_matrix(n, 1.0);
    ASSERT_TRUE(factor.factorize_positive_definite(matrix));
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(matrix.rows(), -1.0, 1.0);
    const Eigen::VectorXd exact = factor.solve(b);
    const Eigen::VectorXd single = factor.solve_single_precision(b);
    ASSERT_EQ(single.size(), exact.size());
    EXPECT_LT((single - exact).norm(), 1e-5 * exact.norm()) << n << "^3 points";
  }
}

TEST(DirectFactorization, AnotherPatternIsAnalysedAgainWithoutBeingTold) {
  // Two callers of one factorisation (the planning equilibrium, then the prediction's Newton
  // steps) share its analysis where their patterns agree; where they do not, it analyses
  // again by itself, and the answer is right.
  DirectFactorization factor;
  const SparseMatrix plain = grid_matrix(8, 1.0);
  const SparseMatrix denser = grid_matrix(8, 1.0, true);  // the same size, more entries
  ASSERT_EQ(plain.rows(), denser.rows());
  ASSERT_GT(denser.nonZeros(), plain.nonZeros());
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(plain.rows(), -1.0, 1.0);
  const auto residual = [&](const SparseMatrix& matrix) {
    const Eigen::VectorXd x = factor.solve(b);
    return (matrix.selfadjointView<Eigen::Lower>() * x - b).norm() / b.norm();
  };
  ASSERT_TRUE(factor.factorize_positive_definite(plain));
  EXPECT_LT(residual(plain), 1e-12);
  EXPECT_EQ(factor.analyses(), 1);
  ASSERT_TRUE(factor.factorize_positive_definite(grid_matrix(8, 3.0)));  // same pattern
  EXPECT_EQ(factor.analyses(), 1);
  EXPECT_LT(residual(grid_matrix(8, 3.0)), 1e-12);
  ASSERT_TRUE(factor.factorize(denser));
  EXPECT_EQ(factor.analyses(), 2);
  EXPECT_LT(residual(denser), 1e-12);
  ASSERT_TRUE(factor.factorize_positive_definite(plain));  // back again
  EXPECT_EQ(factor.analyses(), 3);
  EXPECT_LT(residual(plain), 1e-12);
}

TEST(DirectFactorization, AFactorBeyondAFloatsRangeIsSolvedInDouble) {
  if (!has_cholmod_backend()) {
    GTEST_SKIP() << "built without CHOLMOD: solve_single_precision is solve";
  }
  // Entries of 1e80 (N/m in absurd units): the factor's 1e40 overflows a float.
  const SparseMatrix matrix = grid_matrix(6, 1e80);
  DirectFactorization factor;
  ASSERT_TRUE(factor.factorize_positive_definite(matrix));
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(matrix.rows());
  const Eigen::VectorXd single = factor.solve_single_precision(b);
  EXPECT_TRUE(single.allFinite());
  EXPECT_EQ(single, factor.solve(b));
}

}  // namespace
}  // namespace incise
