// Static equilibrium by Newton's method with a backtracking line search on the potential
// energy.

#include <algorithm>
#include <cmath>
#include <limits>

#include "incise/core/error.hpp"
#include "incise/solve/integrators.hpp"

namespace incise {

namespace {
/// A stalled solve counts as converged within this factor of the tolerance.
constexpr double kFloorFactor = 1e3;
/// Only Newton steps solved this accurately can show a floor (inexact CG steps may not halve
/// the residual while still making progress).
constexpr double kExactLinearSolve = 1e-6;
}  // namespace

StaticEquilibrium::StaticEquilibrium(const StaticOptions& options)
    : options_(options), solver_(options.solver) {
  if (options_.max_iterations < 1 || !(options_.tolerance > 0.0)) {
    throw InputError("static solve needs at least one iteration and a positive tolerance");
  }
}

bool StaticEquilibrium::solve(DynamicSystem& system, std::span<Vec3> x, double t) {
  system.refresh();
  const std::size_t n = x.size();
  constrained_.assign(n, 0);
  zero_.assign(n, Vec3::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    const auto vertex = static_cast<VertexId>(i);
    if (system.is_constrained(vertex)) {
      constrained_[i] = 1;
      Vec3 velocity;
      system.prescribed_state(t, vertex, x[i], velocity);
    }
  }
  force_.resize(n);
  step_.assign(n, Vec3::Zero());
  trial_.resize(n);
  auto free_norm = [&](std::span<const Vec3> field) {
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (constrained_[i] == 0) {
        sum += field[i].squaredNorm();
      }
    }
    return std::sqrt(sum);
  };
  // The load scale: external forces on the free vertices.
  std::fill(force_.begin(), force_.end(), Vec3::Zero());
  system.external_forces(t, force_);
  double reference = free_norm(force_);
  last_iterations_ = 0;
  last_linear_iterations_ = 0;
  last_factorization_seconds_ = 0.0;
  double energy = system.potential_energy(t, x);
  // Force sums cancel to a rounding floor (polar decompositions, large internal forces against
  // small loads) that can lie above a strict tolerance: three iterations in a row that do not
  // halve the best residual mean the floor is reached, and the solve stops there.
  double best_residual = std::numeric_limits<double>::infinity();
  int stalled = 0;
  bool last_step_exact = false;  ///< the last Newton step's linear solve met 1e-6
  for (int iteration = 0; iteration < options_.max_iterations; ++iteration) {
    std::fill(force_.begin(), force_.end(), Vec3::Zero());
    system.forces(t, x, zero_, force_);
    const double residual = free_norm(force_);
    if (iteration == 0 && reference == 0.0) {
      reference = residual;
    }
    last_residual_ = reference > 0.0 ? residual / reference : 0.0;
    if (!std::isfinite(residual)) {
      return false;
    }
    if (residual <= options_.tolerance * reference || residual == 0.0) {
      return true;
    }
    if (residual < 0.5 * best_residual) {
      best_residual = residual;
      stalled = 0;
    } else if (last_step_exact && ++stalled >= 3) {
      return residual <= kFloorFactor * options_.tolerance * reference;
    }
    system.prepare_linearization(t, x, zero_);
    // Newton step: K dx = f on the free vertices (warm start from the last step).
    solver_.set_linearization_positions(x);
    const LinearSolveStats linear =
        solver_.solve(system, 0.0, 1.0, 0.0, constrained_, force_, step_);
    last_linear_iterations_ += linear.iterations;
    last_solve_direct_ = linear.direct;
    last_factorization_seconds_ += linear.seconds_preconditioner;
    last_step_exact = linear.relative_residual <= kExactLinearSolve;
    double slope = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (constrained_[i] == 0) {
        slope += force_[i].dot(step_[i]);
      }
    }
    if (!(slope > 0.0)) {
      // Not a descent direction (the linear solve failed): fall back to the force itself.
      for (std::size_t i = 0; i < n; ++i) {
        step_[i] = constrained_[i] == 0 ? force_[i] : Vec3::Zero();
      }
      slope = free_norm(force_) * free_norm(force_);
    }
    // Armijo backtracking on the potential energy.
    double length = 1.0;
    bool accepted = false;
    for (int halving = 0; halving < 30; ++halving) {
      for (std::size_t i = 0; i < n; ++i) {
        trial_[i] = constrained_[i] == 0 ? Vec3(x[i] + length * step_[i]) : x[i];
      }
      const double trial_energy = system.potential_energy(t, trial_);
      if (std::isfinite(trial_energy) && trial_energy <= energy - 1e-4 * length * slope) {
        energy = trial_energy;
        accepted = true;
        break;
      }
      length *= 0.5;
    }
    if (!accepted) {
      // Energy differences are below rounding: take the full Newton step (near a solution).
      for (std::size_t i = 0; i < n; ++i) {
        trial_[i] = constrained_[i] == 0 ? Vec3(x[i] + step_[i]) : x[i];
      }
      energy = system.potential_energy(t, trial_);
    }
    std::copy(trial_.begin(), trial_.end(), x.begin());
    ++last_iterations_;
    ++stats_.force_evaluations;
  }
  std::fill(force_.begin(), force_.end(), Vec3::Zero());
  system.forces(t, x, zero_, force_);
  last_residual_ = reference > 0.0 ? free_norm(force_) / reference : 0.0;
  return last_residual_ <= options_.tolerance;
}

void StaticEquilibrium::step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
                             double dt) {
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw InputError("time step must be positive and finite");
  }
  (void)solve(system, x, t + dt);
  std::fill(v.begin(), v.end(), Vec3::Zero());
  stats_.vertex_updates += x.size();
  stats_.touched_last_step = x.size();
  stats_.solver_iterations_last_step = static_cast<std::size_t>(last_iterations_);
  stats_.solver_residual_last_step = last_residual_;
}

}  // namespace incise
