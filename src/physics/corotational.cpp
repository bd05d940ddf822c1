#include "incise/physics/corotational.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <string>

#include "incise/core/error.hpp"

namespace incise {

namespace {

constexpr double kInverseSqrt2 = 0.70710678118654752440;

/// Frobenius inner product A : B.
double contract(const Mat3& a, const Mat3& b) {
  return a.cwiseProduct(b).sum();
}

}  // namespace

LameParameters lame_parameters(double young_modulus, double poisson_ratio) {
  return {young_modulus / (2.0 * (1.0 + poisson_ratio)),
          young_modulus * poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio))};
}

TetRestShape tet_rest_shape(const Corners& rest, std::int64_t element) {
  Mat3 edges;
  edges.col(0) = rest[1] - rest[0];
  edges.col(1) = rest[2] - rest[0];
  edges.col(2) = rest[3] - rest[0];
  const double volume = edges.determinant() / 6.0;
  const double scale = std::max({edges.col(0).norm(), edges.col(1).norm(), edges.col(2).norm()});
  const std::string name = element >= 0 ? "tetrahedron " + std::to_string(element) : "tetrahedron";
  if (!std::isfinite(volume) || !(scale > 0.0)) {
    throw InputError(name + " has non-finite or coincident corners");
  }
  if (volume <= 1e-12 * scale * scale * scale) {
    throw InputError(name + (volume < 0.0 ? " is inverted" : " is degenerate") +
                     " in the rest configuration (volume " + std::to_string(volume) + " m^3)");
  }
  // Rows of the inverse edge matrix are the gradients of N_1..N_3; N_0's is minus their sum.
  const Mat3 inverse = edges.inverse();
  TetRestShape shape;
  shape.volume = volume;
  shape.gradients[1] = inverse.row(0).transpose();
  shape.gradients[2] = inverse.row(1).transpose();
  shape.gradients[3] = inverse.row(2).transpose();
  shape.gradients[0] = -(shape.gradients[1] + shape.gradients[2] + shape.gradients[3]);
  return shape;
}

Mat3 deformation_gradient(const Corners& x, const TetRestShape& rest) {
  Mat3 F = x[0] * rest.gradients[0].transpose();
  for (int a = 1; a < 4; ++a) {
    F.noalias() += x[a] * rest.gradients[a].transpose();
  }
  return F;
}

Mat3 polar_rotation_svd(const Mat3& F) {
  Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  const Mat3& V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) {
    U.col(2) = -U.col(2);  // flip the direction of the smallest singular value
  }
  return U * V.transpose();
}

Mat3 polar_rotation(const Mat3& F, Eigen::Quaterniond& warm_start) {
  if (!F.allFinite()) {
    warm_start.setIdentity();
    return Mat3::Identity();
  }
  // Newton's method on skew(R^T F) = 0: with S = sym(R^T F) and a = axial(skew(R^T F)), the
  // body-frame turn w solves (tr(S) I - S) w = 2 a (quadratic convergence: two or three
  // iterations from a warm start). Where tr(S) I - S is not safely positive definite (far
  // from the answer, or a nearly flat element) a step of Mueller et al. 2016 is taken instead:
  // a turn about sum_i r_i x f_i, which always increases tr(R^T F).
  constexpr int kMaxIterations = 60;
  const double scale = F.norm();
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    const Mat3 R = warm_start.toRotationMatrix();
    const Mat3 local = R.transpose() * F;
    const Vec3 asymmetry(0.5 * (local(2, 1) - local(1, 2)), 0.5 * (local(0, 2) - local(2, 0)),
                         0.5 * (local(1, 0) - local(0, 1)));
    const Mat3 S = 0.5 * (local + local.transpose());
    const Mat3 G = S.trace() * Mat3::Identity() - S;
    // G is symmetric: its adjugate has six distinct entries, and Sylvester's criterion on the
    // leading minors says whether G is positive definite.
    const double adj00 = G(1, 1) * G(2, 2) - G(1, 2) * G(1, 2);
    const double adj01 = G(0, 2) * G(1, 2) - G(0, 1) * G(2, 2);
    const double adj02 = G(0, 1) * G(1, 2) - G(0, 2) * G(1, 1);
    const double adj11 = G(0, 0) * G(2, 2) - G(0, 2) * G(0, 2);
    const double adj12 = G(0, 1) * G(0, 2) - G(0, 0) * G(1, 2);
    const double adj22 = G(0, 0) * G(1, 1) - G(0, 1) * G(0, 1);
    const double determinant = G(0, 0) * adj00 + G(0, 1) * adj01 + G(0, 2) * adj02;
    if (G(0, 0) > 0.0 && adj22 > 0.0 && determinant > 1e-6 * scale * scale * scale) {
      const double factor = 2.0 / determinant;
      const Vec3 turn(
          factor * (adj00 * asymmetry.x() + adj01 * asymmetry.y() + adj02 * asymmetry.z()),
          factor * (adj01 * asymmetry.x() + adj11 * asymmetry.y() + adj12 * asymmetry.z()),
          factor * (adj02 * asymmetry.x() + adj12 * asymmetry.y() + adj22 * asymmetry.z()));
      const double angle = turn.norm();
      if (angle < 1e-14 * (1.0 + scale)) {
        return R;
      }
      if (angle < 0.5) {
        const Eigen::Quaterniond step(1.0, 0.5 * turn.x(), 0.5 * turn.y(), 0.5 * turn.z());
        warm_start = warm_start * step;  // body frame: R <- R exp(W), first order, renormalised
        warm_start.normalize();
        if (angle < 1e-6) {
          // Quadratic convergence: what is left after this turn is of order angle^2, below
          // 1e-12 rad (the stress error it makes is far below the solver's tolerance).
          return warm_start.toRotationMatrix();
        }
        continue;
      }
    }
    const Vec3 torque =
        R.col(0).cross(F.col(0)) + R.col(1).cross(F.col(1)) + R.col(2).cross(F.col(2));
    const double alignment =
        std::abs(R.col(0).dot(F.col(0)) + R.col(1).dot(F.col(1)) + R.col(2).dot(F.col(2)));
    const Vec3 omega = torque / (alignment + 1e-9 * scale + 1e-300);
    const double angle = omega.norm();
    if (angle < 1e-14) {
      return R;
    }
    warm_start = Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle)) * warm_start;
    warm_start.normalize();
  }
  // Slow convergence near a degenerate state: take the exact answer.
  const Mat3 R = polar_rotation_svd(F);
  warm_start = Eigen::Quaterniond(R);
  return R;
}

Mat3 polar_rotation(const Mat3& F) {
  Eigen::Quaterniond start = Eigen::Quaterniond::Identity();
  return polar_rotation(F, start);
}

double corotated_energy_density(const Mat3& F, const Mat3& R, const LameParameters& lame) {
  const double volumetric = contract(R, F) - 3.0;
  return lame.mu * (F - R).squaredNorm() + 0.5 * lame.lambda * volumetric * volumetric;
}

Mat3 corotated_stress(const Mat3& F, const Mat3& R, const LameParameters& lame) {
  return 2.0 * lame.mu * (F - R) + lame.lambda * (contract(R, F) - 3.0) * R;
}

double corotated_energy(const Corners& x, const TetRestShape& rest, const LameParameters& lame,
                        double weight) {
  const Mat3 F = deformation_gradient(x, rest);
  return weight * rest.volume * corotated_energy_density(F, polar_rotation(F), lame);
}

ElementForces corotated_forces(const Mat3& F, const Mat3& R, const TetRestShape& rest,
                               const LameParameters& lame, double weight) {
  const Mat3 scaled_stress = (-weight * rest.volume) * corotated_stress(F, R, lame);
  ElementForces forces;
  for (int a = 0; a < 4; ++a) {
    forces[a] = scaled_stress * rest.gradients[a];
  }
  return forces;
}

ElementForces corotated_forces(const Corners& x, const TetRestShape& rest,
                               const LameParameters& lame, double weight) {
  const Mat3 F = deformation_gradient(x, rest);
  return corotated_forces(F, polar_rotation(F), rest, lame, weight);
}

CorotatedLinearization corotated_linearization(const Mat3& F, const Mat3& R,
                                               const LameParameters& lame, TangentKind kind) {
  CorotatedLinearization linearization;
  linearization.rotation = R;
  if (kind == TangentKind::kWarped) {
    linearization.warped = true;
    linearization.twist_weights = {-2.0 * lame.mu, -2.0 * lame.mu, -2.0 * lame.mu};
    return linearization;
  }
  Mat3 S = R.transpose() * F;
  S = 0.5 * (S + S.transpose()).eval();
  Eigen::SelfAdjointEigenSolver<Mat3> eigen;
  eigen.computeDirect(S);
  const Vec3& sigma = eigen.eigenvalues();
  const Mat3& V = eigen.eigenvectors();
  const double trace = sigma.sum();
  const double coefficient = lame.lambda * (trace - 3.0) - 2.0 * lame.mu;
  // s_i + s_j >= 0 for the closest rotation; it reaches 0 only for a flattened element.
  const double floor = 1e-8 * std::max(1.0, std::abs(trace));
  constexpr int kPairs[3][2] = {{1, 2}, {2, 0}, {0, 1}};
  for (int k = 0; k < 3; ++k) {
    const int i = kPairs[k][0];
    const int j = kPairs[k][1];
    const double sum = std::max(sigma[i] + sigma[j], floor);
    double eigenvalue = 2.0 * lame.mu + 2.0 * coefficient / sum;
    if (kind == TangentKind::kProjected) {
      eigenvalue = std::max(eigenvalue, 0.0);
    }
    linearization.twist_modes[k] =
        kInverseSqrt2 * R * (V.col(j) * V.col(i).transpose() - V.col(i) * V.col(j).transpose());
    linearization.twist_weights[k] = eigenvalue - 2.0 * lame.mu;
  }
  return linearization;
}

Mat3 stress_differential(const CorotatedLinearization& linearization, const LameParameters& lame,
                         const Mat3& dF) {
  if (linearization.warped) {
    return warped_stress_differential(linearization.rotation, lame, dF);
  }
  Mat3 dP = 2.0 * lame.mu * dF +
            (lame.lambda * contract(linearization.rotation, dF)) * linearization.rotation;
  for (int k = 0; k < 3; ++k) {
    dP += (linearization.twist_weights[k] * contract(linearization.twist_modes[k], dF)) *
          linearization.twist_modes[k];
  }
  return dP;
}

Mat3 warped_stress_differential(const Mat3& R, const LameParameters& lame, const Mat3& dF) {
  const Mat3 local = R.transpose() * dF;
  const Mat3 strain = 0.5 * (local + local.transpose());
  return R * (2.0 * lame.mu * strain + lame.lambda * strain.trace() * Mat3::Identity());
}

Mat3 stiffness_block(const CorotatedLinearization& linearization, const LameParameters& lame,
                     const TetRestShape& rest, double weight, int a, int b) {
  const Vec3& ga = rest.gradients[a];
  const Vec3& gb = rest.gradients[b];
  const Vec3 ra = linearization.rotation * ga;
  const Vec3 rb = linearization.rotation * gb;
  if (linearization.warped) {
    Mat3 block = Mat3::Zero();
    const double factor = weight * rest.volume;
    add_warped_stiffness_block(block, (factor * lame.lambda) * ra, (factor * lame.mu) * ra, rb,
                               factor * lame.mu * ga.dot(gb));
    return block;
  }
  Mat3 block = (2.0 * lame.mu * ga.dot(gb)) * Mat3::Identity() + lame.lambda * ra * rb.transpose();
  for (int k = 0; k < 3; ++k) {
    block += linearization.twist_weights[k] * (linearization.twist_modes[k] * ga) *
             (linearization.twist_modes[k] * gb).transpose();
  }
  return (weight * rest.volume) * block;
}

ElementMatrix corotated_stiffness(const Corners& x, const TetRestShape& rest,
                                  const LameParameters& lame, TangentKind kind, double weight) {
  const Mat3 F = deformation_gradient(x, rest);
  const CorotatedLinearization linearization =
      corotated_linearization(F, polar_rotation(F), lame, kind);
  ElementMatrix K;
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      K.block<3, 3>(3 * a, 3 * b) = stiffness_block(linearization, lame, rest, weight, a, b);
    }
  }
  return K;
}

ElementForces linear_forces(const Corners& x, const Corners& rest_positions,
                            const TetRestShape& rest, const LameParameters& lame) {
  Mat3 displacement_gradient = Mat3::Zero();
  for (int a = 0; a < 4; ++a) {
    displacement_gradient += (x[a] - rest_positions[a]) * rest.gradients[a].transpose();
  }
  const Mat3 strain = 0.5 * (displacement_gradient + displacement_gradient.transpose());
  const Mat3 stress = 2.0 * lame.mu * strain + lame.lambda * strain.trace() * Mat3::Identity();
  ElementForces forces;
  for (int a = 0; a < 4; ++a) {
    forces[a] = -rest.volume * stress * rest.gradients[a];
  }
  return forces;
}

}  // namespace incise
