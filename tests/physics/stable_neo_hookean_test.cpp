// The stable Neo-Hookean element maths: no energy or stress at rest, stress and tangent the
// exact derivatives (inverted states included), the convex tangent positive semi-definite,
// rotation invariance, and linear elasticity with the given Lame parameters for small strains.

#include "incise/physics/stable_neo_hookean.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

namespace {

using namespace incise;

const LameParameters kLame = lame_parameters(1e4, 0.45);  // Pa

std::vector<Mat3> sample_gradients() {
  std::mt19937 random(11);
  std::uniform_real_distribution<double> entry(-0.6, 0.6);
  std::vector<Mat3> samples;
  for (int i = 0; i < 40; ++i) {
    Mat3 F = Mat3::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        F(r, c) += entry(random);
      }
    }
    if (i % 4 == 0) {
      F.col(2) *= -0.5;  // inverted
    }
    samples.push_back(F);
  }
  return samples;
}

TEST(StableNeoHookean, NoEnergyNoStressAtRest) {
  const NeoHookeanParameters p = stable_neo_hookean(kLame);
  EXPECT_EQ(neo_hookean_energy_density(Mat3::Identity(), p), 0.0);
  EXPECT_LT(neo_hookean_stress(Mat3::Identity(), p).norm(), 1e-12 * p.mu);
}

TEST(StableNeoHookean, StressAndTangentAreTheExactDerivatives) {
  const NeoHookeanParameters p = stable_neo_hookean(kLame);
  const double h = 1e-6;
  for (const Mat3& F : sample_gradients()) {
    const Mat3 P = neo_hookean_stress(F, p);
    const Mat9 tangent = neo_hookean_tangent(F, p, false);
    for (int k = 0; k < 9; ++k) {
      Mat3 plus = F;
      Mat3 minus = F;
      plus.data()[k] += h;
      minus.data()[k] -= h;
      const double slope =
          (neo_hookean_energy_density(plus, p) - neo_hookean_energy_density(minus, p)) / (2 * h);
      EXPECT_NEAR(P.data()[k], slope, 1e-6 * p.mu);
      const Mat3 dP = (neo_hookean_stress(plus, p) - neo_hookean_stress(minus, p)) / (2 * h);
      for (int j = 0; j < 9; ++j) {
        EXPECT_NEAR(tangent(j, k), dP.data()[j], 1e-5 * p.lambda) << "F =\n" << F;
      }
    }
  }
}

TEST(StableNeoHookean, ConvexTangentIsPositiveSemiDefiniteEverywhere) {
  const NeoHookeanParameters p = stable_neo_hookean(kLame);
  int indefinite_exact = 0;
  for (const Mat3& F : sample_gradients()) {
    const Eigen::SelfAdjointEigenSolver<Mat9> convex(neo_hookean_tangent(F, p, true));
    EXPECT_GT(convex.eigenvalues().minCoeff(), -1e-9 * p.lambda);
    const Eigen::SelfAdjointEigenSolver<Mat9> exact(neo_hookean_tangent(F, p, false));
    indefinite_exact += exact.eigenvalues().minCoeff() < 0.0 ? 1 : 0;
  }
  EXPECT_GT(indefinite_exact, 0) << "the samples should reach states where it matters";
}

TEST(StableNeoHookean, RotationInvariantAndLinearElasticForSmallStrains) {
  const NeoHookeanParameters p = stable_neo_hookean(kLame);
  const Mat3 Q = Eigen::AngleAxisd(0.9, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  for (const Mat3& F : sample_gradients()) {
    EXPECT_NEAR(neo_hookean_energy_density(Q * F, p), neo_hookean_energy_density(F, p),
                1e-9 * p.lambda);
  }
  Mat3 e;
  e << 2, 1, 0, 1, -1, 3, 0, 3, 1;
  for (double scale : {1e-3, 1e-4}) {
    const Mat3 strain = scale * e;
    const double linear =
        kLame.mu * strain.squaredNorm() + 0.5 * kLame.lambda * strain.trace() * strain.trace();
    // Relative error O(strain).
    EXPECT_NEAR(neo_hookean_energy_density(Mat3::Identity() + strain, p), linear,
                20.0 * scale * linear);
  }
}

TEST(StableNeoHookean, ElementForcesAndStiffnessAreDerivativesOfTheEnergy) {
  const NeoHookeanParameters p = stable_neo_hookean(kLame);
  const Corners rest_corners = {Vec3(0, 0, 0), Vec3(0.01, 0, 0), Vec3(0.002, 0.012, 0),
                                Vec3(0.003, 0.004, 0.009)};
  const TetRestShape rest = tet_rest_shape(rest_corners);
  Corners x = rest_corners;
  x[1] += Vec3(0.002, -0.001, 0.0005);
  x[3] += Vec3(-0.004, 0.002, -0.011);  // through the opposite face: inverted
  const ElementForces f = neo_hookean_forces(x, rest, p);
  EXPECT_LT((f[0] + f[1] + f[2] + f[3]).norm(), 1e-12);
  ElementForces both;
  EXPECT_EQ(neo_hookean_energy_and_forces(x, rest, p, both), neo_hookean_energy(x, rest, p));
  for (std::size_t a = 0; a < 4; ++a) {
    EXPECT_EQ(both[a], f[a]);  // the same numbers as the two calls
  }
  const ElementMatrix k = neo_hookean_stiffness(x, rest, p, false);
  EXPECT_LT((k - k.transpose()).norm(), 1e-9 * k.norm());
  // The product without the matrix.
  const ElementForces w = {Vec3(1, -2, 0.5), Vec3(0.3, 0.1, -1), Vec3(-2, 1, 1), Vec3(0, 0.4, 2)};
  const ElementForces kw = neo_hookean_stiffness_product(x, rest, p, w);
  for (std::size_t b = 0; b < 4; ++b) {
    Vec3 expected = Vec3::Zero();
    for (std::size_t a = 0; a < 4; ++a) {
      expected +=
          k.block<3, 3>(static_cast<Eigen::Index>(3 * b), static_cast<Eigen::Index>(3 * a)) * w[a];
    }
    EXPECT_LT((kw[b] - expected).norm(), 1e-9 * k.norm());
  }
  const double h = 1e-8;
  for (std::size_t a = 0; a < 4; ++a) {
    for (int d = 0; d < 3; ++d) {
      Corners plus = x;
      Corners minus = x;
      plus[a][d] += h;
      minus[a][d] -= h;
      const double slope =
          (neo_hookean_energy(plus, rest, p) - neo_hookean_energy(minus, rest, p)) / (2 * h);
      EXPECT_NEAR(-f[a][d], slope, 1e-6 * (1.0 + std::abs(slope)));
      const ElementForces fp = neo_hookean_forces(plus, rest, p);
      const ElementForces fm = neo_hookean_forces(minus, rest, p);
      for (std::size_t b = 0; b < 4; ++b) {
        for (int e = 0; e < 3; ++e) {
          const double numeric = -(fp[b][e] - fm[b][e]) / (2 * h);
          EXPECT_NEAR(k(static_cast<Eigen::Index>(3 * b) + e, static_cast<Eigen::Index>(3 * a) + d),
                      numeric, 1e-5 * k.norm());
        }
      }
    }
  }
}

}  // namespace
