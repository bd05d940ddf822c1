#include "incise/planning/newton.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/planning/prism.hpp"
#include "incise/solve/direct_factorization.hpp"
#include "point_block_matrix.hpp"
#include "tissue_pattern.hpp"

namespace incise::planning {

namespace {

using Clock = std::chrono::steady_clock;

/// Armijo's sufficient-decrease constant and the most halvings of a step.
constexpr double kArmijo = 1e-4;
constexpr int kMaxHalvings = 40;
/// The first relative diagonal shift after an indefinite exact Hessian (ten times larger per
/// further indefinite one, shrunk by 0.3 per accepted step).
constexpr double kFirstShift = 1e-3;
/// A lagged factorisation's conjugate gradients: at most this many, to this relative residual
/// (an inexact Newton step: the line search and the next step correct the rest).
constexpr int kLaggedIterations = 6;
constexpr double kLaggedTolerance = 1e-2;

/// The Hessian of the energy over the free points, the volume term's curvature left out; with
/// `convex`, also the transverse term of compressed springs (negative: they buckle), which makes
/// it positive semi-definite by construction.
void assemble_hessian(const LayeredTissue& tissue, const CouplingPattern& pattern,
                      std::span<const Vec3> x, bool convex, PointBlockMatrix& hessian) {
  hessian.clear();
  for (std::size_t s = 0; s < tissue.springs.size(); ++s) {
    const Spring& spring = tissue.springs[s];
    const Vec3 d = x[static_cast<std::size_t>(spring.a)] - x[static_cast<std::size_t>(spring.b)];
    const double length = d.norm();
    if (!(length > 0.0)) {
      continue;
    }
    const Vec3 u = d / length;
    const double along =
        tissue.law.tension_derivative(length, spring.rest_length, spring.stiffness);
    double across = tissue.law.tension(length, spring.rest_length, spring.stiffness) / length;
    if (convex) {
      across = std::max(across, 0.0);
    }
    const Mat3 block = (along - across) * u * u.transpose() + across * Mat3::Identity();
    hessian.add_diagonal(spring.a, block);
    hessian.add_diagonal(spring.b, block);
    hessian.add_coupling(s, -block);
  }
  if (tissue.elasticity == TissueElasticity::kContinuum) {
    add_tet_stiffness(tissue, pattern, x, convex, hessian);
  }
  if (!(tissue.volume_weight > 0.0)) {
    return;
  }
  for (std::size_t p = 0; p < tissue.prisms.size(); ++p) {
    const Prism& prism = tissue.prisms[p];
    if (prism.rest_volume == 0.0) {
      continue;
    }
    PrismPoints corners;
    for (std::size_t i = 0; i < 6; ++i) {
      corners[i] = x[static_cast<std::size_t>(prism.points[i])];
    }
    const std::array<Vec3, 6> dv = prism_volume_gradient(corners);
    const double weight = tissue.volume_weight / std::abs(prism.rest_volume);
    // kappa / |V0| ((grad V)(grad V)^T + (V - V0) grad^2 V); the convex form keeps the first.
    PrismHessian block;
    for (std::size_t i = 0; i < 6; ++i) {
      for (std::size_t j = 0; j < 6; ++j) {
        block.block<3, 3>(static_cast<Eigen::Index>(3 * i), static_cast<Eigen::Index>(3 * j)) =
            weight * dv[i] * dv[j].transpose();
      }
    }
    if (!convex) {
      block +=
          (weight * (prism_volume(corners) - prism.rest_volume)) * prism_volume_hessian(corners);
    }
    for (std::size_t i = 0, k = 0; i < 6; ++i) {
      const auto bi = static_cast<Eigen::Index>(3 * i);
      hessian.add_diagonal(prism.points[i], block.block<3, 3>(bi, bi));
      for (std::size_t j = i + 1; j < 6; ++j, ++k) {
        const auto bj = static_cast<Eigen::Index>(3 * j);
        const std::size_t pair = pattern.prism_pairs[p * 15 + k];
        // The block at (first, second) of the pair as stored.
        const bool same_order = pattern.pairs[pair].first == prism.points[i];
        hessian.add_coupling(
            pair, same_order ? Mat3(block.block<3, 3>(bi, bj)) : Mat3(block.block<3, 3>(bj, bi)));
      }
    }
  }
}

/// Conjugate gradients on `matrix` (lower triangle stored) preconditioned by `factor` (of an
/// earlier, nearby matrix). False, leaving `x` unusable, on negative curvature or when the
/// relative residual is not below kLaggedTolerance within kLaggedIterations: then the matrix
/// has moved too far from the factorised one and is factorised itself.
bool lagged_solve(const DirectFactorization::SparseMatrix& matrix,
                  const DirectFactorization& factor, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const auto a = matrix.selfadjointView<Eigen::Lower>();
  x = factor.solve(b);
  Eigen::VectorXd r = b - a * x;
  const double b_norm = b.norm();
  if (!(b_norm > 0.0)) {
    return false;
  }
  Eigen::VectorXd z = factor.solve(r);
  Eigen::VectorXd p = z;
  double rz = r.dot(z);
  for (int iteration = 0; iteration < kLaggedIterations; ++iteration) {
    if (r.norm() <= kLaggedTolerance * b_norm) {
      return x.allFinite();
    }
    const Eigen::VectorXd ap = a * p;
    const double curvature = p.dot(ap);
    if (!(curvature > 0.0)) {
      return false;
    }
    const double step = rz / curvature;
    x += step * p;
    r -= step * ap;
    z = factor.solve(r);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return r.norm() <= kLaggedTolerance * b_norm && x.allFinite();
}

}  // namespace

MinimizeResult minimize_newton(const TissueEnergy& energy, std::span<Vec3> x,
                               std::span<const char> free, const MinimizeOptions& options,
                               const MinimizeProgress& progress) {
  const auto start = Clock::now();
  const LayeredTissue& tissue = energy.tissue();
  const std::size_t n = x.size();
  if (n != free.size() || n != tissue.point_count()) {
    throw InputError("minimize_newton: positions, free flags and the tissue differ in size");
  }
  MinimizeResult result;
  std::vector<int> row(n, -1);
  int rows = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (free[i] != 0) {
      row[i] = rows;
      rows += 3;
    }
  }
  std::vector<Vec3> g(n);
  double value = energy.energy(x, g);
  result.evaluations = 1;
  result.initial_value = value;
  result.initial_gradient = largest_free(g, free);
  double gradient = result.initial_gradient;
  if (rows == 0 || gradient <= options.gradient_tolerance) {
    result.converged = true;
    result.final_value = value;
    result.final_gradient = gradient;
    result.message = rows == 0 ? "no free points" : "converged";
    result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    return result;
  }

  const CouplingPattern pattern = coupling_pattern(tissue);
  PointBlockMatrix hessian(row, rows, pattern.pairs);
  DirectFactorization factorization;  // analysed on the first step, refactorised after
  double damping = 0.0;               // relative, grown only when a step fails
  double shift = 0.0;                 // relative, after an indefinite exact Hessian
  bool have_factor = false;
  int non_descent_steps = 0;
  double best_gradient = gradient;
  int steps_since_best = 0;
  std::vector<Vec3> trial(x.begin(), x.end());
  std::vector<Vec3> trial_gradient(n);
  Eigen::VectorXd rhs(rows);
  result.message = "iteration limit";
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    for (std::size_t i = 0; i < n; ++i) {
      if (row[i] >= 0) {
        rhs.segment<3>(row[i]) = -g[i];
      }
    }
    // The exact Hessian, shifted by a multiple of its diagonal after indefinite ones
    // (Levenberg-Marquardt; the shift decays as steps succeed).
    assemble_hessian(tissue, pattern, x, false, hessian);
    hessian.damp_diagonal(damping + shift, 0.0);
    Eigen::VectorXd step;
    // First, conjugate gradients on it preconditioned by the last factorisation: a few solves
    // with a factor already paid for, instead of a new factorisation, while the Hessian has not
    // moved far from the one factorised.
    bool lagged = have_factor && lagged_solve(hessian.matrix(), factorization, rhs, step) &&
                  rhs.dot(step) > 0.0;  // a descent direction
    if (lagged) {
      ++result.lagged_steps;
    } else {
      // A factorisation of the exact Hessian where it is positive definite: fast convergence
      // near the minimum. Else of its convex part, which always gives a descent direction.
      bool factorized = factorization.factorize_positive_definite(hessian.matrix());
      if (!factorized) {
        shift = shift == 0.0 ? kFirstShift : shift * 10.0;
        ++result.convexified_steps;
        assemble_hessian(tissue, pattern, x, true, hessian);
        hessian.damp_diagonal(std::max(damping, 1e-12), 0.0);
        factorized = factorization.factorize(hessian.matrix());
      }
      have_factor = factorized;
      if (!factorized) {
        if (damping >= 1.0) {
          throw InputError(
              "Newton's prediction: the tissue's stiffness matrix cannot be factorised "
              "(a free point held by no spring?)");
        }
        damping = std::max(1e-6, damping * 10.0);
        continue;
      }
      ++result.factorizations;
      step = factorization.solve(rhs);
    }
    const double slope = -rhs.dot(step);  // g . p
    if (!(slope < 0.0)) {
      // A factorised matrix that gave no descent direction (rounding in a nearly singular
      // one): damp it more. Never more than ten times: then the gradient is at its floor.
      if (++non_descent_steps > 10) {
        result.message = "no descent direction (the rounding floor)";
        result.converged = gradient <= 1e3 * options.gradient_tolerance;
        break;
      }
      damping = std::max(1e-6, damping * 10.0);
      continue;
    }
    // Backtracking on the energy. Near the minimum the energy's decrease falls below its
    // rounding; a step that still reduces the gradient is then taken.
    double alpha = 1.0;
    bool accepted = false;
    for (int halving = 0; halving < kMaxHalvings && !accepted; ++halving, alpha *= 0.5) {
      for (std::size_t i = 0; i < n; ++i) {
        if (row[i] >= 0) {
          trial[i] = x[i] + alpha * Vec3(step.segment<3>(row[i]));
        }
      }
      const double trial_value = energy.energy(trial, trial_gradient);
      ++result.evaluations;
      if (!std::isfinite(trial_value)) {
        continue;
      }
      const bool sufficient = trial_value <= value + kArmijo * alpha * slope;
      const bool at_rounding =
          trial_value <= value && largest_free(trial_gradient, free) < gradient;
      if (sufficient || at_rounding) {
        accepted = true;
        value = trial_value;
        std::copy(trial.begin(), trial.end(), x.begin());
        std::swap(g, trial_gradient);
      }
    }
    if (!accepted) {
      result.message = "line search found no decrease (the rounding floor)";
      result.converged = gradient <= 1e3 * options.gradient_tolerance;
      break;
    }
    damping *= 0.1;
    if (damping < 1e-9) {
      damping = 0.0;
    }
    shift *= 0.3;
    if (shift < 1e-6) {
      shift = 0.0;
    }
    result.iterations = iteration + 1;
    gradient = largest_free(g, free);
    // Newton halves the gradient within a few steps until rounding stops it: twenty steps
    // without halving the best so far mean the floor.
    if (gradient < 0.5 * best_gradient) {
      best_gradient = gradient;
      steps_since_best = 0;
    } else if (++steps_since_best >= 20 && gradient > options.gradient_tolerance) {
      result.message = "the gradient stopped decreasing (the rounding floor)";
      result.converged = gradient <= 1e3 * options.gradient_tolerance;
      break;
    }
    if (progress) {
      progress(result.iterations, gradient);
    }
    if (gradient <= options.gradient_tolerance) {
      result.converged = true;
      result.message = "converged";
      break;
    }
  }
  result.final_value = value;
  result.final_gradient = gradient;
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace incise::planning
