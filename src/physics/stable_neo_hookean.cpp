#include "incise/physics/stable_neo_hookean.hpp"

#include <array>
#include <cmath>

namespace incise {

namespace {

double alpha(const NeoHookeanParameters& p) {
  return 1.0 + 0.75 * p.mu / p.lambda;
}

/// The cofactor matrix dJ/dF: its columns are f1 x f2, f2 x f0, f0 x f1.
Mat3 cofactor(const Mat3& F) {
  Mat3 c;
  c.col(0) = F.col(1).cross(F.col(2));
  c.col(1) = F.col(2).cross(F.col(0));
  c.col(2) = F.col(0).cross(F.col(1));
  return c;
}

Eigen::Map<const Eigen::Matrix<double, 9, 1>> as_vector(const Mat3& m) {
  return Eigen::Map<const Eigen::Matrix<double, 9, 1>>(m.data());
}

}  // namespace

NeoHookeanParameters stable_neo_hookean(const LameParameters& lame) {
  return {4.0 / 3.0 * lame.mu, lame.lambda + 5.0 / 6.0 * lame.mu};
}

double neo_hookean_energy_density(const Mat3& F, const NeoHookeanParameters& p) {
  // Written in H = F - I so that nothing of the order of mu cancels (the constants of Psi and
  // its terms linear in H cancel analytically): a minimiser compares energies that differ by
  // far less than mu times the volume.
  const Mat3 h = F - Mat3::Identity();
  const double trace = h.trace();
  const double ic_minus_3 = 2.0 * trace + h.squaredNorm();
  // J - 1 = tr H + (tr^2 H - tr H^2) / 2 + det H.
  const double j_minus_1 = trace + 0.5 * (trace * trace - (h * h).trace()) + h.determinant();
  const double delta = alpha(p) - 1.0;
  return 0.5 * p.mu * ic_minus_3 - 0.5 * p.mu * std::log1p(0.25 * ic_minus_3) +
         0.5 * p.lambda * j_minus_1 * (j_minus_1 - 2.0 * delta);
}

Mat3 neo_hookean_stress(const Mat3& F, const NeoHookeanParameters& p) {
  const double ic = F.squaredNorm();
  return p.mu * (1.0 - 1.0 / (ic + 1.0)) * F +
         p.lambda * (F.determinant() - alpha(p)) * cofactor(F);
}

Mat3 neo_hookean_stress_differential(const Mat3& F, const Mat3& dF, const NeoHookeanParameters& p) {
  const double ic = F.squaredNorm();
  const Mat3 cof = cofactor(F);
  // d(cof F): d(f1 x f2) = df1 x f2 + f1 x df2, cyclically.
  Mat3 dcof;
  dcof.col(0) = dF.col(1).cross(F.col(2)) + F.col(1).cross(dF.col(2));
  dcof.col(1) = dF.col(2).cross(F.col(0)) + F.col(2).cross(dF.col(0));
  dcof.col(2) = dF.col(0).cross(F.col(1)) + F.col(0).cross(dF.col(1));
  return p.mu * (1.0 - 1.0 / (ic + 1.0)) * dF +
         (2.0 * p.mu / ((ic + 1.0) * (ic + 1.0)) * F.cwiseProduct(dF).sum()) * F +
         (p.lambda * cof.cwiseProduct(dF).sum()) * cof +
         (p.lambda * (F.determinant() - alpha(p))) * dcof;
}

Mat9 neo_hookean_tangent(const Mat3& F, const NeoHookeanParameters& p, bool convex) {
  const double ic = F.squaredNorm();
  const Mat3 cof = cofactor(F);
  Mat9 h = p.mu * (1.0 - 1.0 / (ic + 1.0)) * Mat9::Identity();
  h.noalias() += (2.0 * p.mu / ((ic + 1.0) * (ic + 1.0))) * as_vector(F) * as_vector(F).transpose();
  h.noalias() += p.lambda * as_vector(cof) * as_vector(cof).transpose();
  if (!convex) {
    // H_J: block (k, l) = d(column k of cof F) / d(column l of F).
    const double s = p.lambda * (F.determinant() - alpha(p));
    const Mat3 x0 = s * cross_matrix(F.col(0));
    const Mat3 x1 = s * cross_matrix(F.col(1));
    const Mat3 x2 = s * cross_matrix(F.col(2));
    h.block<3, 3>(0, 3) -= x2;
    h.block<3, 3>(0, 6) += x1;
    h.block<3, 3>(3, 0) += x2;
    h.block<3, 3>(3, 6) -= x0;
    h.block<3, 3>(6, 0) -= x1;
    h.block<3, 3>(6, 3) += x0;
  }
  return h;
}

double neo_hookean_energy(const Corners& x, const TetRestShape& rest,
                          const NeoHookeanParameters& p) {
  return rest.volume * neo_hookean_energy_density(deformation_gradient(x, rest), p);
}

namespace {

ElementForces forces_from(const Mat3& F, const TetRestShape& rest, const NeoHookeanParameters& p) {
  const Mat3 stress = neo_hookean_stress(F, p);
  ElementForces f;
  for (std::size_t a = 0; a < 4; ++a) {
    f[a] = -rest.volume * (stress * rest.gradients[a]);
  }
  return f;
}

}  // namespace

ElementForces neo_hookean_forces(const Corners& x, const TetRestShape& rest,
                                 const NeoHookeanParameters& p) {
  return forces_from(deformation_gradient(x, rest), rest, p);
}

double neo_hookean_energy_and_forces(const Corners& x, const TetRestShape& rest,
                                     const NeoHookeanParameters& p, ElementForces& forces) {
  const Mat3 F = deformation_gradient(x, rest);
  forces = forces_from(F, rest, p);
  return rest.volume * neo_hookean_energy_density(F, p);
}

ElementForces neo_hookean_stiffness_product(const Corners& x, const TetRestShape& rest,
                                            const NeoHookeanParameters& p, const ElementForces& w) {
  Mat3 dF = Mat3::Zero();
  for (std::size_t a = 0; a < 4; ++a) {
    dF.noalias() += w[a] * rest.gradients[a].transpose();
  }
  const Mat3 dP = neo_hookean_stress_differential(deformation_gradient(x, rest), dF, p);
  ElementForces kw;
  for (std::size_t a = 0; a < 4; ++a) {
    kw[a] = rest.volume * (dP * rest.gradients[a]);
  }
  return kw;
}

ElementStiffnessBlocks neo_hookean_stiffness_blocks(const Corners& x, const TetRestShape& rest,
                                                    const NeoHookeanParameters& p, bool convex) {
  // K_ab = V B_a^T (dP/dF) B_b with dvec(F)/dx_b = B_b = [g_b(0) I; g_b(1) I; g_b(2) I] (F(i, k)
  // = sum_b x_b(i) g_b(k)). Each term of the tangent (neo_hookean_tangent) contracts in closed
  // form: the identity to (g_a . g_b) I, vec(F) vec(F)^T to (F g_a)(F g_b)^T, vec(cof F)
  // vec(cof F)^T to (cof F g_a)(cof F g_b)^T, and the determinant's curvature (block (k, l) of
  // d(cof F)/dF is -eps_klm [f_m]x) to -[F (g_a x g_b)]x: 3x3 blocks from 3-vectors, without
  // the 9x9 tangent (a third of the operations).
  const Mat3 F = deformation_gradient(x, rest);
  const Mat3 cof = cofactor(F);
  const double ic = F.squaredNorm();
  const double volume = rest.volume;
  const double identity = volume * p.mu * (1.0 - 1.0 / (ic + 1.0));
  const double along_f = volume * 2.0 * p.mu / ((ic + 1.0) * (ic + 1.0));
  const double along_cof = volume * p.lambda;
  const double curvature = convex ? 0.0 : volume * p.lambda * (F.determinant() - alpha(p));
  std::array<Vec3, 4> fg;
  std::array<Vec3, 4> cg;
  for (std::size_t a = 0; a < 4; ++a) {
    fg[a] = F * rest.gradients[a];
    cg[a] = cof * rest.gradients[a];
  }
  ElementStiffnessBlocks blocks;
  for (std::size_t a = 0, k = 0; a < 4; ++a) {
    const Vec3& ga = rest.gradients[a];
    for (std::size_t b = a; b < 4; ++b, ++k) {
      const Vec3& gb = rest.gradients[b];
      Mat3& block = blocks[k];
      block.noalias() = (along_f * fg[a]) * fg[b].transpose();
      block.noalias() += (along_cof * cg[a]) * cg[b].transpose();
      block.diagonal().array() += identity * ga.dot(gb);
      if (b != a && curvature != 0.0) {
        block -= cross_matrix(curvature * (F * ga.cross(gb)));
      }
    }
  }
  return blocks;
}

ElementMatrix neo_hookean_stiffness(const Corners& x, const TetRestShape& rest,
                                    const NeoHookeanParameters& p, bool convex) {
  const ElementStiffnessBlocks blocks = neo_hookean_stiffness_blocks(x, rest, p, convex);
  ElementMatrix k;
  for (std::size_t a = 0, next = 0; a < 4; ++a) {
    for (std::size_t b = a; b < 4; ++b, ++next) {
      const auto ia = static_cast<Eigen::Index>(3 * a);
      const auto ib = static_cast<Eigen::Index>(3 * b);
      k.block<3, 3>(ia, ib) = blocks[next];
      if (b != a) {
        k.block<3, 3>(ib, ia) = blocks[next].transpose();
      }
    }
  }
  return k;
}

}  // namespace incise
