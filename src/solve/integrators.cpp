#include "incise/solve/integrators.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/timing.hpp"

namespace incise {
namespace {

/// a = f / m for free vertices, 0 for constrained or massless ones.
void divide_by_mass(const DynamicSystem& system, std::span<const Vec3> f, std::span<Vec3> a) {
  const auto masses = system.masses();
  for (std::size_t i = 0; i < a.size(); ++i) {
    const bool free = !system.is_constrained(static_cast<VertexId>(i)) && masses[i] > 0.0;
    a[i] = free ? Vec3(f[i] / masses[i]) : Vec3::Zero();
  }
}

void constrain(DynamicSystem& system, double t, std::span<Vec3> x, std::span<Vec3> v) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (system.is_constrained(static_cast<VertexId>(i))) {
      system.prescribed_state(t, static_cast<VertexId>(i), x[i], v[i]);
    }
  }
}

void check_step(double dt) {
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw InputError("time step must be positive and finite");
  }
}

}  // namespace

double explicit_stability_limit(const DynamicSystem& system, const std::string& scheme) {
  const double omega = system.max_frequency();
  if (omega <= 0.0) {
    return std::numeric_limits<double>::infinity();
  }
  // Undamped oscillator: Euler-type schemes need omega dt < 2, RK4 omega dt < 2.78.
  return (scheme == "rk4" || scheme == "rk4-hierarchical" ? 2.78 : 2.0) / omega;
}

double Integrator::stability_limit(const DynamicSystem& system) const {
  return explicit_stability_limit(system, "explicit-euler");
}
double RungeKutta4::stability_limit(const DynamicSystem& system) const {
  return explicit_stability_limit(system, "rk4");
}
double HierarchicalRungeKutta4::stability_limit(const DynamicSystem& /*system*/) const {
  return std::numeric_limits<double>::infinity();
}
double BackwardEuler::stability_limit(const DynamicSystem& /*system*/) const {
  return std::numeric_limits<double>::infinity();
}
double StaticEquilibrium::stability_limit(const DynamicSystem& /*system*/) const {
  return std::numeric_limits<double>::infinity();
}

// ---- Euler ----------------------------------------------------------------------------------

namespace {

/// One first-order step: explicit Euler moves x with the old velocity, symplectic Euler with
/// the new one; everything else is the same.
void euler_step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t, double dt,
                bool symplectic, std::vector<Vec3>& force, IntegratorStats& stats) {
  check_step(dt);
  system.refresh();
  system.begin_step(t, x, v);
  force.assign(x.size(), Vec3::Zero());
  system.forces(t, x, v, force);
  divide_by_mass(system, force, force);
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (symplectic) {
      v[i] += dt * force[i];
      x[i] += dt * v[i];
    } else {
      x[i] += dt * v[i];
      v[i] += dt * force[i];
    }
  }
  constrain(system, t + dt, x, v);
  system.end_step(dt, v);
  system.finish_step(t + dt, x, v);
  ++stats.force_evaluations;
  stats.vertex_updates += x.size();
  stats.touched_last_step = x.size();
}

}  // namespace

void ExplicitEuler::step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
                         double dt) {
  euler_step(system, x, v, t, dt, false, force_, stats_);
}

void SymplecticEuler::step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
                           double dt) {
  euler_step(system, x, v, t, dt, true, force_, stats_);
}

// ---- RK4 ------------------------------------------------------------------------------------

void RungeKutta4::accelerations(DynamicSystem& system, double t, std::span<const Vec3> x,
                                std::span<const Vec3> v, std::span<Vec3> a) {
  force_.assign(x.size(), Vec3::Zero());
  system.forces(t, x, v, force_);
  divide_by_mass(system, force_, a);
  ++stats_.force_evaluations;
}

void RungeKutta4::step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
                       double dt) {
  check_step(dt);
  system.refresh();
  system.begin_step(t, x, v);
  const std::size_t n = x.size();
  resize_for_edits(xs_, n);
  resize_for_edits(vs_, n);
  for (int s = 0; s < 4; ++s) {
    resize_for_edits(k_[s], n);
    resize_for_edits(l_[s], n);
  }
  // Seed eq. 5 with its typesetting slips corrected: the velocity estimates are
  // k2 = v + dt/2 l1, k3 = v + dt/2 l2, k4 = v + dt l3 (the seed prints l_i dt), as in the
  // classical method it cites.
  constexpr double kStageFraction[4] = {0.0, 0.5, 0.5, 1.0};
  for (int s = 0; s < 4; ++s) {
    const double h = kStageFraction[s] * dt;
    for (std::size_t i = 0; i < n; ++i) {
      xs_[i] = s == 0 ? x[i] : Vec3(x[i] + h * k_[s - 1][i]);
      vs_[i] = s == 0 ? v[i] : Vec3(v[i] + h * l_[s - 1][i]);
    }
    constrain(system, t + h, xs_, vs_);
    for (std::size_t i = 0; i < n; ++i) {
      k_[s][i] = vs_[i];
    }
    accelerations(system, t + h, xs_, vs_, l_[s]);
  }
  for (std::size_t i = 0; i < n; ++i) {
    x[i] += dt / 6.0 * (k_[0][i] + 2.0 * k_[1][i] + 2.0 * k_[2][i] + k_[3][i]);
    v[i] += dt / 6.0 * (l_[0][i] + 2.0 * l_[1][i] + 2.0 * l_[2][i] + l_[3][i]);
  }
  constrain(system, t + dt, x, v);
  system.end_step(dt, v);
  system.finish_step(t + dt, x, v);
  stats_.vertex_updates += n;
  stats_.touched_last_step = n;
}

// ---- hierarchical RK4 -----------------------------------------------------------------------

HierarchicalRungeKutta4::HierarchicalRungeKutta4(const HierarchicalOptions& options)
    : options_(options) {
  if (options_.iterations < 1 || options_.iterations > 1 << 20) {
    throw InputError("hierarchical RK4 needs at least one iteration at the focus");
  }
  if (options_.max_depth < 0) {
    throw InputError("hierarchical RK4 maximum depth must be non-negative");
  }
}

int HierarchicalRungeKutta4::iterations_at_depth(int depth) const {
  if (depth < 0 || depth > options_.max_depth) {
    return 0;
  }
  const double share = options_.iterations * std::ldexp(1.0, -depth);
  return std::max(1, static_cast<int>(std::ceil(share - 1e-9)));
}

void HierarchicalRungeKutta4::step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v,
                                   double t, double dt) {
  check_step(dt);
  system.refresh();
  system.begin_step(t, x, v);
  // Vertices are coupled explicitly (neighbours are extrapolated over the whole sweep), so a
  // sweep may not be longer than the explicit limit of the coupled system; per-vertex
  // sub-steps only resolve each vertex's own motion. The seed keeps dt below that limit; a
  // longer step is split into sweeps here.
  const double limit = sweep_fraction_ * explicit_stability_limit(system, "rk4");
  const int sweeps = std::isfinite(limit) && limit > 0.0
                         ? std::max(1, static_cast<int>(std::ceil(dt / limit - 1e-9)))
                         : 1;
  std::size_t touched = 0;
  for (int k = 0; k < sweeps; ++k) {
    sweep(system, x, v, t + dt * k / sweeps, dt / sweeps);
    touched = std::max(touched, stats_.touched_last_step);
  }
  stats_.touched_last_step = touched;
  last_sweeps_ = sweeps;
  system.finish_step(t + dt, x, v);
}

void HierarchicalRungeKutta4::sweep(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v,
                                    double t, double dt) {
  const std::size_t n = x.size();
  const double end = t + dt;
  // Vertices created since the last step (a cut) start up to date. Depths are cleared where
  // the last sweep set them, not over the whole body.
  stamp_.resize(n, t);
  depth_.resize(n, -1);
  for (VertexId vertex : order_) {
    if (static_cast<std::size_t>(vertex) < n) {
      depth_[static_cast<std::size_t>(vertex)] = -1;
    }
  }
  order_.clear();

  // Breadth-first order from the focus, or every vertex at depth 0 without one.
  if (focus_ == kInvalidId) {
    for (std::size_t i = 0; i < n; ++i) {
      depth_[i] = 0;
      order_.push_back(static_cast<VertexId>(i));
    }
  } else {
    if (focus_ < 0 || static_cast<std::size_t>(focus_) >= n) {
      throw InputError("hierarchical RK4 focus vertex " + std::to_string(focus_) +
                       " does not exist");
    }
    depth_[focus_] = 0;
    order_.push_back(focus_);
    for (std::size_t head = 0; head < order_.size(); ++head) {
      const VertexId vertex = order_[head];
      if (depth_[vertex] == options_.max_depth) {
        continue;
      }
      for (VertexId neighbor : system.neighbors(vertex)) {
        if (depth_[neighbor] < 0) {
          depth_[neighbor] = depth_[vertex] + 1;
          order_.push_back(neighbor);
        }
      }
    }
  }

  const auto masses = system.masses();
  // Step bound from the system's highest frequency: catch-up intervals are subdivided so no
  // sub-step is unstable (the seed leaves this to the choice of dt).
  const double stable = 0.9 * explicit_stability_limit(system, "rk4");
  // Neighbour state at time tau: prescribed, or extrapolated with its velocity from its stamp;
  // extrapolation reaches at most one step, so frozen far vertices do not drift.
  double tau = t;
  const NeighborState neighbor = [&](VertexId j, Vec3& xj, Vec3& vj) {
    if (system.is_constrained(j)) {
      system.prescribed_state(tau, j, xj, vj);
      return;
    }
    const double lag = std::clamp(tau - stamp_[static_cast<std::size_t>(j)], -dt, dt);
    xj = x[static_cast<std::size_t>(j)] + lag * v[static_cast<std::size_t>(j)];
    vj = v[static_cast<std::size_t>(j)];
  };

  for (VertexId vertex : order_) {
    const auto i = static_cast<std::size_t>(vertex);
    if (system.is_constrained(vertex)) {
      system.prescribed_state(end, vertex, x[i], v[i]);
      stamp_[i] = end;
      continue;
    }
    // Catch up at most a few steps: far from the focus this is relaxation, not history.
    const double elapsed = std::min(end - stamp_[i], 4.0 * dt);
    const double mass = masses[i];
    if (elapsed <= 0.0 || mass <= 0.0) {
      stamp_[i] = end;
      continue;
    }
    int substeps =
        iterations_at_depth(depth_[i]) * static_cast<int>(std::ceil(elapsed / dt - 1e-9));
    if (std::isfinite(stable) && stable > 0.0) {
      substeps = std::max(substeps, static_cast<int>(std::ceil(elapsed / stable)));
    }
    const double h = elapsed / substeps;
    double time = end - elapsed;
    Vec3 xi = x[i];
    Vec3 vi = v[i];
    auto acceleration = [&](double at, const Vec3& position, const Vec3& velocity) {
      tau = at;
      return Vec3(system.vertex_force(at, vertex, position, velocity, neighbor) / mass);
    };
    for (int s = 0; s < substeps; ++s) {
      const Vec3 k1 = vi;
      const Vec3 l1 = acceleration(time, xi, vi);
      const Vec3 k2 = vi + 0.5 * h * l1;
      const Vec3 l2 = acceleration(time + 0.5 * h, xi + 0.5 * h * k1, k2);
      const Vec3 k3 = vi + 0.5 * h * l2;
      const Vec3 l3 = acceleration(time + 0.5 * h, xi + 0.5 * h * k2, k3);
      const Vec3 k4 = vi + h * l3;
      const Vec3 l4 = acceleration(time + h, xi + h * k3, k4);
      xi += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      vi += h / 6.0 * (l1 + 2.0 * l2 + 2.0 * l3 + l4);
      time += h;
    }
    system.end_step(elapsed, vertex, vi);
    x[i] = xi;
    v[i] = vi;
    stamp_[i] = end;
    stats_.vertex_updates += static_cast<std::uint64_t>(substeps);
  }
  stats_.touched_last_step = order_.size();
}

// ---- backward Euler -------------------------------------------------------------------------

BackwardEuler::BackwardEuler(const BackwardEulerOptions& options)
    : options_(options), solver_(options.solver) {
  if (options_.newton_steps < 1) {
    throw InputError("backward Euler needs at least one Newton step");
  }
}

void BackwardEuler::step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
                         double dt) {
  check_step(dt);
  const auto step_start = Clock::now();
  system.refresh();
  stats_.seconds_refresh = seconds_since(step_start);
  system.begin_step(t, x, v);
  const std::size_t n = x.size();
  const auto masses = system.masses();
  const double end = t + dt;
  constrained_.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    constrained_[i] = system.is_constrained(static_cast<VertexId>(i)) || masses[i] <= 0.0 ? 1 : 0;
  }
  // Unknown: the end velocity v1. Newton on r(v1) = M (v1 - v0) - dt f(x0 + dt v1, v1) with
  // Jacobian J = M + dt D + dt^2 K, from v1 = v0 (prescribed velocities for held vertices).
  v_trial_.assign(v.begin(), v.end());
  resize_for_edits(x_trial_, n);
  for (std::size_t i = 0; i < n; ++i) {
    if (system.is_constrained(static_cast<VertexId>(i))) {
      Vec3 position;
      system.prescribed_state(end, static_cast<VertexId>(i), position, v_trial_[i]);
    }
  }
  resize_for_edits(force_, n);
  resize_for_edits(rhs_, n);
  resize_for_edits(delta_, n);
  // A cut added vertices: earlier solutions are carried onto them as positions are, so the
  // next solve still starts close (clearing the history cost a cutting frame 1.8x the CG
  // iterations of a frame that does not cut).
  for (auto& solution : history_) {
    if (solution.size() > n) {
      history_.clear();
      break;
    }
    system.extend_vertex_values(solution);
  }
  stats_.solver_iterations_last_step = 0;
  stats_.seconds_forces = 0.0;
  stats_.seconds_preconditioner = 0.0;
  stats_.seconds_products = 0.0;
  stats_.seconds_vector_updates = 0.0;
  stats_.seconds_solver_start = 0.0;

  for (int newton = 0; newton < options_.newton_steps; ++newton) {
    for (std::size_t i = 0; i < n; ++i) {
      x_trial_[i] = x[i] + dt * v_trial_[i];
    }
    // Forces and the linearisation at the same state in one call, so models share per-element
    // work (the FEM computes each rotation once). Every iteration, the first included, is a
    // Newton step at the current guess (x0 + dt v1, v1), starting from v1 = v0: linearising at
    // x0 instead (Baraff and Witkin's one step) damps more, by 4 % of the peers' box sag at
    // 48k tets after 1 s.
    const auto forces_start = Clock::now();
    std::fill(force_.begin(), force_.end(), Vec3::Zero());
    system.forces_and_linearization(end, x_trial_, v_trial_, force_);
    stats_.seconds_forces += seconds_since(forces_start);
    for (std::size_t i = 0; i < n; ++i) {
      rhs_[i] = dt * force_[i] - masses[i] * (v_trial_[i] - v[i]);
    }
    std::fill(delta_.begin(), delta_.end(), Vec3::Zero());
    std::vector<std::span<const Vec3>> basis;
    if (newton == 0 && options_.solver.start_history > 0) {
      // Start from the best combination of the last steps' velocity changes: from the
      // linear extrapolation of the last two, the 48k-tet box needs 111 CG iterations per
      // step instead of 67 (BENCHMARKS.md).
      basis.assign(history_.begin(), history_.end());
    } else if (newton == 0 && history_.size() >= 2) {
      for (std::size_t i = 0; i < n; ++i) {
        delta_[i] = 2.0 * history_[0][i] - history_[1][i];
      }
    }
    ++stats_.force_evaluations;
    solver_.set_linearization_positions(x_trial_);
    const LinearSolveStats solve =
        solver_.solve(system, 1.0, dt * dt, dt, constrained_, rhs_, delta_, basis);
    stats_.solver_iterations_last_step += static_cast<std::size_t>(solve.iterations);
    stats_.solver_residual_last_step = solve.relative_residual;
    stats_.seconds_preconditioner += solve.seconds_preconditioner;
    stats_.seconds_products += solve.seconds_products;
    stats_.seconds_vector_updates += solve.seconds_vector_updates;
    stats_.seconds_solver_start += solve.seconds_start;
    for (std::size_t i = 0; i < n; ++i) {
      if (constrained_[i] == 0) {
        v_trial_[i] += delta_[i];
      }
    }
    if (newton == 0) {
      // Keep the newest first; the oldest buffer is reused.
      const std::size_t keep = static_cast<std::size_t>(std::max(2, options_.solver.start_history));
      if (history_.size() < keep) {
        history_.emplace_back();
      }
      std::rotate(history_.rbegin(), history_.rbegin() + 1, history_.rend());
      history_.front().assign(delta_.begin(), delta_.end());
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (system.is_constrained(static_cast<VertexId>(i))) {
      system.prescribed_state(end, static_cast<VertexId>(i), x[i], v[i]);
    } else if (masses[i] > 0.0) {
      v[i] = v_trial_[i];
      x[i] += dt * v[i];
    }
  }
  system.end_step(dt, v);
  system.finish_step(end, x, v);
  stats_.vertex_updates += n;
  stats_.touched_last_step = n;
  stats_.seconds_step = seconds_since(step_start);
}

// ---- checkpoints ----------------------------------------------------------------------------

void BackwardEuler::save_state(StateWriter& out) const {
  out.tag("backward euler");
  out.nested(history_);
  solver_.save_state(out);
}

void BackwardEuler::load_state(StateReader& in) {
  in.tag("backward euler");
  history_ = in.nested<Vec3>("earlier solutions");
  solver_.load_state(in);
}

void HierarchicalRungeKutta4::save_state(StateWriter& out) const {
  out.tag("hierarchical rk4");
  out.value(focus_);
  out.value(last_sweeps_);
  out.values(stamp_);
}

void HierarchicalRungeKutta4::load_state(StateReader& in) {
  in.tag("hierarchical rk4");
  focus_ = in.value<VertexId>("focus");
  last_sweeps_ = in.value<int>("sweeps");
  stamp_ = in.values<double>("vertex time stamps");
}

}  // namespace incise
