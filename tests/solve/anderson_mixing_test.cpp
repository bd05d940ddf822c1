// Anderson mixing of a slowly converging linear fixed-point iteration: the same fixed point in
// several times fewer steps, and the plain iteration at depth 0.

#include "incise/solve/anderson_mixing.hpp"

#include <gtest/gtest.h>

#include <random>

namespace incise {
namespace {

/// Steps of u <- u + r(u), r(u) = D^-1 (b - A u) (Jacobi's iteration on a diagonally dominant
/// A whose off-diagonal part makes it converge at about 0.9 per step), to |r| < 1e-10 |b|.
int steps_to_converge(int depth, Eigen::VectorXd& u) {
  constexpr int kSize = 60;
  std::mt19937 random(3);
  std::uniform_real_distribution<double> entry(0.0, 1.0);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(kSize, kSize);
  for (int i = 0; i < kSize; ++i) {
    for (int j = 0; j < kSize; ++j) {
      a(i, j) = i == j ? 1.0 : 0.9 * entry(random) / (kSize / 2.0);
    }
  }
  a = (0.5 * (a + a.transpose())).eval();
  Eigen::VectorXd b(kSize);
  for (int i = 0; i < kSize; ++i) {
    b[i] = entry(random);
  }
  AndersonMixing mixing(depth);
  u = Eigen::VectorXd::Zero(kSize);
  for (int step = 1; step <= 2000; ++step) {
    const Eigen::VectorXd r = (b - a * u).cwiseQuotient(a.diagonal());
    if (r.norm() < 1e-10 * b.norm()) {
      return step;
    }
    u = mixing.next(u, r);
  }
  return -1;
}

TEST(AndersonMixing, ReachesTheSameFixedPointInSeveralTimesFewerSteps) {
  Eigen::VectorXd plain;
  Eigen::VectorXd mixed;
  const int plain_steps = steps_to_converge(0, plain);
  const int mixed_steps = steps_to_converge(5, mixed);
  ASSERT_GT(plain_steps, 0);
  ASSERT_GT(mixed_steps, 0);
  EXPECT_GT(plain_steps, 100);  // the plain iteration is slow here
  EXPECT_LT(3 * mixed_steps, plain_steps) << plain_steps << " plain, " << mixed_steps << " mixed";
  EXPECT_LT((mixed - plain).norm(), 1e-8 * plain.norm());
}

TEST(AndersonMixing, DepthZeroAndARestartGiveThePlainStep) {
  AndersonMixing none(0);
  AndersonMixing mixing(3);
  const Eigen::VectorXd u = Eigen::VectorXd::Constant(4, 1.0);
  const Eigen::VectorXd r = Eigen::VectorXd::LinSpaced(4, 0.0, 3.0);
  EXPECT_EQ(none.next(u, r), u + r);
  EXPECT_EQ(mixing.next(u, r), u + r);  // nothing to mix yet
  (void)mixing.next(u + r, 0.5 * r);
  mixing.restart();
  EXPECT_EQ(mixing.next(u, r), u + r);
}

}  // namespace
}  // namespace incise
