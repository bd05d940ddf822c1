#pragma once
// Element maths of corotated linear tetrahedra (Mueller and Gross 2004; seed 003, appendix B),
// as pure functions of corner positions and rest data, testable without a mesh.
//
// With F = R S the polar decomposition of the deformation gradient (R a rotation, also for
// inverted elements, where S then has one negative eigenvalue), the element energy is
//   E = w V [ mu |F - R|^2 + lambda / 2 (tr(R^T F) - 3)^2 ]                          (J)
// and the nodal forces f_a = -w V P grad N_a with the first Piola-Kirchhoff stress
//   P = 2 mu (F - R) + lambda (tr(R^T F) - 3) R                                     (Pa)
// which is exactly the seed's f = R K (R^T p - p0) and exactly -dE/dx: the variation of R
// drops out because R^T F is symmetric. w is the element's material fraction (1 by default;
// XFEM's virtual elements scale their share with it).
//
// The tangent dP = 2 mu dF + lambda tr(R^T dF) R + c dR, with c = lambda (tr S - 3) - 2 mu,
// has eigenvalue 2 mu + 2 c / (s_i + s_j) on the three "twist" modes R (v_i v_j^T - v_j v_i^T)
// (s, v: eigenpairs of S) and is positive semi-definite elsewhere. Three variants:
//   kExact      that tangent (the true derivative of the forces; indefinite under compression);
//   kProjected  the twist eigenvalues clamped at 0: positive semi-definite, equal to kExact
//               wherever those are non-negative; Newton's choice;
//   kWarped     the twist eigenvalues set to 0 (R K0 R^T, Mueller and Gross's stiffness
//               warping): positive semi-definite, needs no eigen-decomposition.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "incise/core/types.hpp"

namespace incise {

using Corners = std::array<Vec3, 4>;
using ElementForces = std::array<Vec3, 4>;
using ElementMatrix = Eigen::Matrix<double, 12, 12>;

/// Lame parameters (Pa).
struct LameParameters {
  double mu = 0.0;      ///< shear modulus (Pa)
  double lambda = 0.0;  ///< first Lame parameter (Pa)
};

/// Lame parameters from Young's modulus (Pa) and Poisson's ratio.
[[nodiscard]] LameParameters lame_parameters(double young_modulus, double poisson_ratio);

/// Rest data of one linear tetrahedron.
struct TetRestShape {
  /// Gradients of the four shape functions in the rest configuration (1/m); they sum to 0.
  std::array<Vec3, 4> gradients{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  double volume = 0.0;  ///< m^3
};

/// Rest data from rest corner positions (m). Throws InputError naming `element` if the
/// tetrahedron is inverted or degenerate (relative volume below 1e-12).
[[nodiscard]] TetRestShape tet_rest_shape(const Corners& rest, std::int64_t element = -1);

/// F = sum_a x_a (grad N_a)^T (dimensionless).
[[nodiscard]] Mat3 deformation_gradient(const Corners& x, const TetRestShape& rest);

/// Rotation of the polar decomposition F = R S (det R = +1 even if det F <= 0: then R is the
/// closest rotation, argmax tr(R^T F)). Iterates from `warm_start` (updated in place) after
/// Mueller et al. 2016, "A robust method to extract the rotational part of deformations";
/// falls back to an SVD when that has not converged. Never NaN for finite F.
[[nodiscard]] Mat3 polar_rotation(const Mat3& F, Eigen::Quaterniond& warm_start);
[[nodiscard]] Mat3 polar_rotation(const Mat3& F);
/// The same from a singular value decomposition (the reference for tests).
[[nodiscard]] Mat3 polar_rotation_svd(const Mat3& F);

/// Energy density (J/m^3) and first Piola-Kirchhoff stress (Pa) for F with rotation R.
[[nodiscard]] double corotated_energy_density(const Mat3& F, const Mat3& R,
                                              const LameParameters& lame);
[[nodiscard]] Mat3 corotated_stress(const Mat3& F, const Mat3& R, const LameParameters& lame);

/// Element energy (J) and nodal forces (N) with material fraction `weight`.
[[nodiscard]] double corotated_energy(const Corners& x, const TetRestShape& rest,
                                      const LameParameters& lame, double weight = 1.0);
[[nodiscard]] ElementForces corotated_forces(const Corners& x, const TetRestShape& rest,
                                             const LameParameters& lame, double weight = 1.0);
/// Forces from a known rotation (what a model with cached rotations calls).
[[nodiscard]] ElementForces corotated_forces(const Mat3& F, const Mat3& R, const TetRestShape& rest,
                                             const LameParameters& lame, double weight);

enum class TangentKind { kExact, kProjected, kWarped };

/// The tangent dP/dF at one state, in the form 2 mu I + lambda r r^T + sum_k c_k t_k t_k^T
/// (r = vec R, t_k = vec twist_modes[k], unit Frobenius norm, c_k = twist eigenvalue - 2 mu).
struct CorotatedLinearization {
  /// kWarped: the twist weights are all -2 mu and the modes span {dF : R^T dF skew}; the fast
  /// paths use R K0 R^T directly and leave twist_modes unset.
  bool warped = false;
  Mat3 rotation = Mat3::Identity();  ///< R of the polar decomposition F = R S
  /// t_k, unit Frobenius norm (unset when warped).
  std::array<Mat3, 3> twist_modes{Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};
  std::array<double, 3> twist_weights{};  ///< c_k (Pa)
};

[[nodiscard]] CorotatedLinearization corotated_linearization(const Mat3& F, const Mat3& R,
                                                             const LameParameters& lame,
                                                             TangentKind kind);
/// dP for a change dF of the deformation gradient (Pa).
[[nodiscard]] Mat3 stress_differential(const CorotatedLinearization& linearization,
                                       const LameParameters& lame, const Mat3& dF);
/// Linear elastic stress of the corotated frame applied to dF (R K0 R^T: the warped tangent),
/// used for stiffness-proportional damping.
[[nodiscard]] Mat3 warped_stress_differential(const Mat3& R, const LameParameters& lame,
                                              const Mat3& dF);
/// 3x3 block (a, b) of the element stiffness K = -df/dx = d^2E/dx^2 (N/m).
[[nodiscard]] Mat3 stiffness_block(const CorotatedLinearization& linearization,
                                   const LameParameters& lame, const TetRestShape& rest,
                                   double weight, int a, int b);
/// Adds the warped block factor * R K0_ab R^T to `block`, where
///   R K0_ab R^T = mu (g_a . g_b) I + lambda r_a r_b^T + mu r_b r_a^T,  r = R g
/// (g = grad N, factor: weight times rest volume, times any scale). Takes the row corner's
/// factors ready made, lambda_a = factor lambda r_a and mu_a = factor mu r_a, and
/// diagonal = factor mu g_a . g_b, because assembly reuses them for the four blocks of a row.
/// Inline and accumulating in place: assembly calls it 16 times per element.
inline void add_warped_stiffness_block(Mat3& block, const Vec3& lambda_a, const Vec3& mu_a,
                                       const Vec3& rotated_b, double diagonal) {
  block.noalias() += lambda_a * rotated_b.transpose();
  block.noalias() += rotated_b * mu_a.transpose();
  block.diagonal().array() += diagonal;
}
/// The whole 12x12 element stiffness (N/m), corners in order, x, y, z per corner.
[[nodiscard]] ElementMatrix corotated_stiffness(const Corners& x, const TetRestShape& rest,
                                                const LameParameters& lame, TangentKind kind,
                                                double weight = 1.0);

/// Plain (not corotated) linear elastic forces (N): wrong under rotation, kept to show it.
[[nodiscard]] ElementForces linear_forces(const Corners& x, const Corners& rest_positions,
                                          const TetRestShape& rest, const LameParameters& lame);

}  // namespace incise
