#pragma once
// Element maths of the stable Neo-Hookean material (Smith, de Goes and Kim 2018, "Stable
// Neo-Hookean Flesh Simulation"), as pure functions of the deformation gradient and of corner
// positions and rest data, testable without a mesh:
//   Psi(F) = mu / 2 (I_C - 3) + lambda / 2 (J - alpha)^2 - mu / 2 log(I_C + 1) - Psi0   (J/m^3)
// with I_C = |F|^2, J = det F, alpha = 1 + 3 mu / (4 lambda) (no stress at rest) and Psi0 the
// constant that makes Psi(I) = 0. Unlike the corotated model it is smooth for every F,
// inverted ones included (no polar decomposition whose branch can jump), and it stiffens
// under compression, so Newton's method converges where a step in a bone's motion crushes and
// shears thin tissue. Its linearisation at rest is linear elasticity with the Lame parameters
// it was made from (mu = 4/3 mu_L, lambda = lambda_L + 5/6 mu_L).
//
// Tangent: dP/dF = c1 I + c2 f f^T + lambda g g^T + lambda (J - alpha) H_J (f = vec F, g =
// vec cof F, H_J the Hessian of det, c1 = mu (1 - 1 / (I_C + 1)) >= 0, c2 = 2 mu / (I_C+1)^2).
// Only the last term is indefinite; the convex form leaves it out (positive semi-definite by
// construction, exact where J = alpha). Vectors of F are column-major: F(i, k) at i + 3 k.

#include <Eigen/Core>
#include <array>

#include "incise/physics/corotational.hpp"

namespace incise {

/// The stable Neo-Hookean energy's parameters (Smith et al. 2018), not Lame's: see
/// stable_neo_hookean().
struct NeoHookeanParameters {
  double mu = 0.0;      ///< Pa
  double lambda = 0.0;  ///< Pa
};

/// The parameters whose linearisation has these Lame parameters (Pa).
[[nodiscard]] NeoHookeanParameters stable_neo_hookean(const LameParameters& lame);

using Mat9 = Eigen::Matrix<double, 9, 9>;

[[nodiscard]] double neo_hookean_energy_density(const Mat3& F, const NeoHookeanParameters& p);
/// First Piola-Kirchhoff stress dPsi/dF (Pa).
[[nodiscard]] Mat3 neo_hookean_stress(const Mat3& F, const NeoHookeanParameters& p);
/// dP for a change dF of the deformation gradient (Pa), exact: the tangent applied without
/// forming it.
[[nodiscard]] Mat3 neo_hookean_stress_differential(const Mat3& F, const Mat3& dF,
                                                   const NeoHookeanParameters& p);
/// dP/dF (Pa), exact or its convex form.
[[nodiscard]] Mat9 neo_hookean_tangent(const Mat3& F, const NeoHookeanParameters& p, bool convex);

/// Element energy (J) and nodal forces -dE/dx (N) of a linear tetrahedron.
[[nodiscard]] double neo_hookean_energy(const Corners& x, const TetRestShape& rest,
                                        const NeoHookeanParameters& p);
[[nodiscard]] ElementForces neo_hookean_forces(const Corners& x, const TetRestShape& rest,
                                               const NeoHookeanParameters& p);
/// Both, from one deformation gradient (the same numbers as the two calls).
[[nodiscard]] double neo_hookean_energy_and_forces(const Corners& x, const TetRestShape& rest,
                                                   const NeoHookeanParameters& p,
                                                   ElementForces& forces);
/// The stiffness applied to corner displacements w: (d^2E/dx^2) w (N), exact.
[[nodiscard]] ElementForces neo_hookean_stiffness_product(const Corners& x,
                                                          const TetRestShape& rest,
                                                          const NeoHookeanParameters& p,
                                                          const ElementForces& w);
/// The 3x3 blocks K_ab of d^2E/dx^2 (N/m) with a <= b, in the order (0,0), (0,1), (0,2),
/// (0,3), (1,1), (1,2), (1,3), (2,2), (2,3), (3,3) (K_ba = K_ab^T): exact, or positive
/// semi-definite.
using ElementStiffnessBlocks = std::array<Mat3, 10>;
[[nodiscard]] ElementStiffnessBlocks neo_hookean_stiffness_blocks(const Corners& x,
                                                                  const TetRestShape& rest,
                                                                  const NeoHookeanParameters& p,
                                                                  bool convex);
/// d^2E/dx^2 (N/m), corners in order, x, y, z per corner: exact, or positive semi-definite.
[[nodiscard]] ElementMatrix neo_hookean_stiffness(const Corners& x, const TetRestShape& rest,
                                                  const NeoHookeanParameters& p, bool convex);

}  // namespace incise
