// Element maths of corotated linear tetrahedra, without a mesh: patch test, invariance under
// rigid motions, forces as the energy's gradient, tangents against finite differences, and
// inversion robustness.

#include "incise/physics/corotational.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

#include "incise/core/error.hpp"

namespace incise {
namespace {

const LameParameters kLame = lame_parameters(3.0e3, 0.45);  // soft tissue, Pa

Corners reference_corners() {
  return {Vec3(0.0, 0.0, 0.0), Vec3(0.011, 0.001, -0.002), Vec3(0.002, 0.009, 0.001),
          Vec3(-0.001, 0.002, 0.012)};
}

Mat3 random_rotation(std::mt19937& random) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(random), normal(random), normal(random), normal(random));
  q.normalize();
  return q.toRotationMatrix();
}

Mat3 random_matrix(std::mt19937& random, double amplitude) {
  std::uniform_real_distribution<double> uniform(-amplitude, amplitude);
  Mat3 m;
  for (int i = 0; i < 9; ++i) {
    m(i) = uniform(random);
  }
  return m;
}

Corners deform(const Corners& rest, const Mat3& F, const Vec3& shift) {
  Corners x;
  for (int a = 0; a < 4; ++a) {
    x[a] = F * rest[a] + shift;
  }
  return x;
}

double max_norm(const ElementForces& f) {
  double m = 0.0;
  for (const Vec3& v : f) {
    m = std::max(m, v.norm());
  }
  return m;
}

/// A typical force scale: stress E times area h^2 for a unit strain.
double force_scale(const TetRestShape& shape) {
  return (2.0 * kLame.mu + kLame.lambda) * std::pow(shape.volume, 2.0 / 3.0);
}

TEST(CorotationalElement, RestShapeGradientsReproduceLinearFields) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  EXPECT_NEAR(shape.volume,
              (rest[1] - rest[0]).cross(rest[2] - rest[0]).dot(rest[3] - rest[0]) / 6.0, 1e-18);
  // Patch test at element level: any affine field x = A X + b gives F = A exactly.
  std::mt19937 random(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Mat3 A = Mat3::Identity() + random_matrix(random, 0.3);
    const Vec3 b = random_matrix(random, 1.0).col(0);
    EXPECT_LT((deformation_gradient(deform(rest, A, b), shape) - A).norm(), 1e-12);
  }
  Vec3 sum = Vec3::Zero();
  for (const Vec3& g : shape.gradients) {
    sum += g;
  }
  EXPECT_LT(sum.norm(), 1e-10 * shape.gradients[1].norm());
}

TEST(CorotationalElement, RejectsInvertedAndDegenerateRestShapes) {
  Corners rest = reference_corners();
  std::swap(rest[1], rest[2]);
  try {
    (void)tet_rest_shape(rest, 42);
    FAIL() << "inverted rest shape accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("tetrahedron 42 is inverted"), std::string::npos)
        << error.what();
  }
  Corners flat = reference_corners();
  flat[3] = 0.5 * (flat[1] + flat[2]);
  EXPECT_THROW((void)tet_rest_shape(flat, 3), InputError);
}

TEST(CorotationalElement, PolarRotationMatchesSvdAlsoForInvertedElements) {
  std::mt19937 random(11);
  for (int trial = 0; trial < 500; ++trial) {
    Mat3 F = random_rotation(random) * (Mat3::Identity() + random_matrix(random, 0.6));
    if (trial % 3 == 0) {
      F.col(trial % 2) *= -1.0;  // an inverted element
    }
    const Mat3 R = polar_rotation(F);
    EXPECT_TRUE(R.allFinite());
    EXPECT_LT((R.transpose() * R - Mat3::Identity()).norm(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    const Mat3 reference = polar_rotation_svd(F);
    // Both maximise tr(R^T F); equal when the singular values are distinct.
    EXPECT_NEAR((R.transpose() * F).trace(), (reference.transpose() * F).trace(), 1e-10);
    const Mat3 S = R.transpose() * F;
    EXPECT_LT((S - S.transpose()).norm(), 1e-10 * F.norm());
  }
  // Flattened and collapsed elements give a rotation, never NaN.
  Mat3 flat = Mat3::Identity();
  flat(2, 2) = 0.0;
  EXPECT_TRUE(polar_rotation(flat).allFinite());
  EXPECT_TRUE(polar_rotation(Mat3::Zero()).allFinite());
}

TEST(CorotationalElement, WarmStartedRotationConvergesToTheSameAnswer) {
  std::mt19937 random(5);
  Eigen::Quaterniond warm = Eigen::Quaterniond::Identity();
  Mat3 F = Mat3::Identity();
  for (int step = 0; step < 200; ++step) {
    F = F * (Mat3::Identity() + random_matrix(random, 0.05));
    const Mat3 R = polar_rotation(F, warm);
    EXPECT_LT((R - polar_rotation(F)).norm(), 1e-9);
  }
}

TEST(CorotationalElement, RigidMotionsGiveNoForceButPlainLinearFemDoes) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  std::mt19937 random(3);
  double worst_linear = 0.0;
  for (int trial = 0; trial < 100; ++trial) {
    const Mat3 Q = random_rotation(random);
    const Vec3 shift = random_matrix(random, 0.1).col(0);
    const Corners moved = deform(rest, Q, shift);
    EXPECT_LT(max_norm(corotated_forces(moved, shape, kLame)), 1e-12 * force_scale(shape));
    EXPECT_LT(corotated_energy(moved, shape, kLame), 1e-24);
    worst_linear = std::max(worst_linear, max_norm(linear_forces(moved, rest, shape, kLame)));
  }
  // Plain linear FEM sees a rotation as strain: ghost forces of order E h^2.
  EXPECT_GT(worst_linear, 0.1 * force_scale(shape));
  // Translation alone is force-free for both.
  const Corners shifted = deform(rest, Mat3::Identity(), Vec3(0.3, -0.2, 0.1));
  EXPECT_LT(max_norm(linear_forces(shifted, rest, shape, kLame)), 1e-12 * force_scale(shape));
}

TEST(CorotationalElement, CorotatedForcesMatchLinearFemForSmallStrain) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  std::mt19937 random(9);
  const Mat3 strain = random_matrix(random, 1e-6);
  const Corners x = deform(rest, Mat3::Identity() + strain, Vec3::Zero());
  const ElementForces corotated = corotated_forces(x, shape, kLame);
  const ElementForces linear = linear_forces(x, rest, shape, kLame);
  for (int a = 0; a < 4; ++a) {
    EXPECT_LT((corotated[a] - linear[a]).norm(), 1e-5 * linear[a].norm() + 1e-20);
  }
}

/// Central differences of the energy along each coordinate.
ElementForces numerical_forces(const Corners& x, const TetRestShape& shape, double h) {
  ElementForces f;
  for (int a = 0; a < 4; ++a) {
    for (int i = 0; i < 3; ++i) {
      Corners plus = x;
      Corners minus = x;
      plus[a][i] += h;
      minus[a][i] -= h;
      f[a][i] = -(corotated_energy(plus, shape, kLame) - corotated_energy(minus, shape, kLame)) /
                (2.0 * h);
    }
  }
  return f;
}

TEST(CorotationalElement, ForcesAreTheNegativeEnergyGradientIncludingInversion) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  std::mt19937 random(21);
  for (int trial = 0; trial < 60; ++trial) {
    Mat3 F = random_rotation(random) * (Mat3::Identity() + random_matrix(random, 0.5));
    if (trial % 4 == 0) {
      F.col(2) *= -0.5;  // inverted
    }
    const Corners x = deform(rest, F, Vec3(0.01, 0.02, -0.01));
    const ElementForces analytic = corotated_forces(x, shape, kLame);
    const ElementForces numeric = numerical_forces(x, shape, 1e-7);
    for (int a = 0; a < 4; ++a) {
      EXPECT_LT((analytic[a] - numeric[a]).norm(), 1e-6 * force_scale(shape))
          << "trial " << trial << " corner " << a;
    }
  }
}

/// Central differences of the forces: K = -df/dx.
ElementMatrix numerical_stiffness(const Corners& x, const TetRestShape& shape, double h) {
  ElementMatrix K;
  for (int b = 0; b < 4; ++b) {
    for (int j = 0; j < 3; ++j) {
      Corners plus = x;
      Corners minus = x;
      plus[b][j] += h;
      minus[b][j] -= h;
      const ElementForces fp = corotated_forces(plus, shape, kLame);
      const ElementForces fm = corotated_forces(minus, shape, kLame);
      for (int a = 0; a < 4; ++a) {
        K.block<3, 1>(3 * a, 3 * b + j) = -(fp[a] - fm[a]) / (2.0 * h);
      }
    }
  }
  return K;
}

TEST(CorotationalElement, ExactTangentMatchesFiniteDifferencesOfTheForces) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  std::mt19937 random(33);
  for (int trial = 0; trial < 60; ++trial) {
    // Stretched, compressed (indefinite tangent) and inverted states.
    Mat3 F = random_rotation(random) * (Mat3::Identity() + random_matrix(random, 0.4));
    if (trial % 5 == 0) {
      F.col(0) *= -0.6;
    }
    const Corners x = deform(rest, F, Vec3::Zero());
    const ElementMatrix exact = corotated_stiffness(x, shape, kLame, TangentKind::kExact);
    const ElementMatrix numeric = numerical_stiffness(x, shape, 1e-8);
    EXPECT_LT((exact - numeric).norm(), 1e-5 * numeric.norm()) << "trial " << trial;
    EXPECT_LT((exact - exact.transpose()).norm(), 1e-12 * exact.norm());
  }
}

TEST(CorotationalElement, ProjectedAndWarpedTangentsArePositiveSemiDefinite) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  std::mt19937 random(44);
  int indefinite_exact = 0;
  for (int trial = 0; trial < 200; ++trial) {
    Mat3 F = random_rotation(random) * (Mat3::Identity() + random_matrix(random, 0.5));
    if (trial % 4 == 0) {
      F.col(1) *= -0.4;
    }
    const Corners x = deform(rest, F, Vec3::Zero());
    const ElementMatrix exact = corotated_stiffness(x, shape, kLame, TangentKind::kExact);
    const double scale = exact.norm();
    for (TangentKind kind : {TangentKind::kProjected, TangentKind::kWarped}) {
      const ElementMatrix K = corotated_stiffness(x, shape, kLame, kind);
      Eigen::SelfAdjointEigenSolver<ElementMatrix> eigen(K);
      EXPECT_GT(eigen.eigenvalues().minCoeff(), -1e-10 * scale) << "trial " << trial;
    }
    Eigen::SelfAdjointEigenSolver<ElementMatrix> exact_eigen(exact);
    if (exact_eigen.eigenvalues().minCoeff() < -1e-6 * scale) {
      ++indefinite_exact;
    } else {
      // Where the exact tangent is already semi-definite, projecting changes nothing.
      const ElementMatrix projected = corotated_stiffness(x, shape, kLame, TangentKind::kProjected);
      EXPECT_LT((projected - exact).norm(), 1e-9 * scale) << "trial " << trial;
    }
  }
  EXPECT_GT(indefinite_exact, 0) << "the sample never reached an indefinite exact tangent";
}

TEST(CorotationalElement, AllTangentsAgreeAtRestWithLinearFem) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  const ElementMatrix warped = corotated_stiffness(rest, shape, kLame, TangentKind::kWarped);
  const ElementMatrix exact = corotated_stiffness(rest, shape, kLame, TangentKind::kExact);
  EXPECT_LT((warped - exact).norm(), 1e-9 * exact.norm());
  // Linear FEM's K0 by finite differences of linear forces.
  ElementMatrix linear;
  const double h = 1e-7;
  for (int b = 0; b < 4; ++b) {
    for (int j = 0; j < 3; ++j) {
      Corners plus = rest;
      plus[b][j] += h;
      const ElementForces f = linear_forces(plus, rest, shape, kLame);
      for (int a = 0; a < 4; ++a) {
        linear.block<3, 1>(3 * a, 3 * b + j) = -f[a] / h;
      }
    }
  }
  EXPECT_LT((warped - linear).norm(), 1e-6 * linear.norm());
}

TEST(CorotationalElement, InvertedElementIsPushedBackAndMaterialFractionScales) {
  const Corners rest = reference_corners();
  const TetRestShape shape = tet_rest_shape(rest);
  // Push corner 3 through the opposite face: the element is inverted.
  Corners x = rest;
  const Vec3 normal = (rest[2] - rest[1]).cross(rest[3] - rest[1]).normalized();
  const Vec3 face_point = rest[1];
  x[0] = rest[0] + 2.0 * (face_point - rest[0]).dot(normal) * normal;
  const ElementForces f = corotated_forces(x, shape, kLame);
  for (const Vec3& v : f) {
    EXPECT_TRUE(v.allFinite());
  }
  // The force on the pushed corner points back towards its rest side of the face.
  EXPECT_LT(f[0].dot(normal), 0.0);
  const ElementForces half = corotated_forces(x, shape, kLame, 0.5);
  for (int a = 0; a < 4; ++a) {
    EXPECT_LT((half[a] - 0.5 * f[a]).norm(), 1e-14 * f[a].norm() + 1e-30);
  }
  EXPECT_NEAR(corotated_energy(x, shape, kLame, 0.25), 0.25 * corotated_energy(x, shape, kLame),
              1e-16);
}

}  // namespace
}  // namespace incise
