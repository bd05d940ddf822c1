#pragma once
// Time integrators for a DynamicSystem. Each advances positions x (m) and velocities v (m/s)
// over dt (s); constrained vertices follow their prescribed motion.

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/physics/dynamic_system.hpp"
#include "incise/solve/linear_solvers.hpp"

namespace incise {

/// What an integrator did: counts over every step and the last step's figures.
struct IntegratorStats {
  std::uint64_t vertex_updates = 0;             ///< single-vertex integration steps (all steps)
  std::uint64_t force_evaluations = 0;          ///< whole-system force evaluations (all steps)
  std::size_t touched_last_step = 0;            ///< vertices advanced by the last step
  std::size_t solver_iterations_last_step = 0;  ///< CG iterations (implicit schemes)
  double solver_residual_last_step = 0.0;       ///< relative residual reached
  /// Where the last step's time went (s): forces together with the linearisation, building the
  /// system matrix and preconditioner or factorisation, matrix-vector products, the whole step.
  double seconds_forces = 0.0;
  double seconds_preconditioner = 0.0;  ///< the system matrix and preconditioner or factor
  double seconds_products = 0.0;        ///< matrix-vector products
  double seconds_vector_updates = 0.0;  ///< CG's vector updates and dot products
  double seconds_solver_start = 0.0;    ///< CG starting guesses from earlier solutions
  /// The model following the last mesh edits (DynamicSystem::refresh) at the step's start.
  double seconds_refresh = 0.0;
  double seconds_step = 0.0;  ///< the whole step
};

/// A time-stepping scheme: advances positions and velocities of a DynamicSystem by one step.
class Integrator {
 public:
  Integrator() = default;
  Integrator(const Integrator&) = delete;
  Integrator& operator=(const Integrator&) = delete;
  virtual ~Integrator() = default;

  [[nodiscard]] virtual std::string name() const = 0;  ///< the scene's name for it
  /// Advances the state from time t to t + dt.
  virtual void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
                    double dt) = 0;
  /// Implicit schemes are stable at any step; explicit ones only below stability_limit().
  [[nodiscard]] virtual bool implicit() const { return false; }
  /// The largest step (s) this scheme takes stably on the system (infinity: any step).
  [[nodiscard]] virtual double stability_limit(const DynamicSystem& system) const;
  /// What the scheme asks of a force model beyond its core (ForceModel's optional
  /// capabilities): forces one vertex at a time, or a linearisation.
  [[nodiscard]] virtual bool needs_vertex_forces() const { return false; }
  [[nodiscard]] virtual bool needs_linearization() const { return false; }  ///< a linearisation (K)
  /// Where the tool acts: schemes that relax locally start there (others ignore it).
  virtual void focus_on(VertexId /*vertex*/) {}
  /// Checkpoints: what a scheme carries from one step to the next (earlier solutions, time
  /// stamps); scratch space is not saved.
  virtual void save_state(StateWriter& /*out*/) const {}
  virtual void load_state(StateReader& /*in*/) {}  ///< restores what save_state() wrote
  [[nodiscard]] const IntegratorStats& stats() const { return stats_; }  ///< what it did

 protected:
  IntegratorStats stats_;  ///< kept up to date by each scheme's step()
};

/// x += dt v, v += dt a(x, v): first order, gains energy; for comparison only.
class ExplicitEuler final : public Integrator {
 public:
  [[nodiscard]] std::string name() const override { return "explicit-euler"; }
  void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
            double dt) override;

 private:
  std::vector<Vec3> force_;
};

/// v += dt a(x, v), then x += dt v: first order, symplectic (bounded energy error).
class SymplecticEuler final : public Integrator {
 public:
  [[nodiscard]] std::string name() const override { return "symplectic-euler"; }
  void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
            double dt) override;

 private:
  std::vector<Vec3> force_;
};

/// Classical fourth-order Runge-Kutta on the first-order system (x' = v, v' = a): the seed's
/// two-level scheme (eqs. 5-6) applied to all vertices at once.
class RungeKutta4 final : public Integrator {
 public:
  [[nodiscard]] std::string name() const override { return "rk4"; }
  void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
            double dt) override;
  [[nodiscard]] double stability_limit(const DynamicSystem& system) const override;

 private:
  void accelerations(DynamicSystem& system, double t, std::span<const Vec3> x,
                     std::span<const Vec3> v, std::span<Vec3> a);
  std::vector<Vec3> xs_, vs_, k_[4], l_[4], force_;
};

/// The hierarchical relaxation's reach (scene keys `integrator.iterations`, `max_depth`).
struct HierarchicalOptions {
  /// I: RK4 sub-steps per step at the focus; a vertex s edges away gets ceil(I / 2^s).
  int iterations = 8;
  /// s_max: vertices further than this from the focus are not advanced.
  int max_depth = 3;
};

/// The seed's hierarchical breadth-first relaxation (section 5.2): vertex-by-vertex RK4 in
/// breadth-first order from a focus vertex (later, the scalpel tip), with i(s) = I 2^-s
/// sub-steps up to depth s_max and none beyond. Each vertex keeps a time stamp and integrates
/// over the time since its last update; neighbours' positions are extrapolated linearly with
/// their velocities. Without a focus every vertex is advanced every step (full relaxation).
class HierarchicalRungeKutta4 final : public Integrator {
 public:
  /// Relaxes as `options` say, with no focus (every vertex) until one is set.
  explicit HierarchicalRungeKutta4(const HierarchicalOptions& options = {});
  [[nodiscard]] std::string name() const override { return "rk4-hierarchical"; }
  void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
            double dt) override;
  /// Splits a step into sweeps within the RK4 limit itself: stable at any dt.
  [[nodiscard]] double stability_limit(const DynamicSystem& system) const override;
  /// Focus of the traversal, or kInvalidId for full relaxation.
  void set_focus(VertexId focus) { focus_ = focus; }
  void focus_on(VertexId vertex) override { focus_ = vertex; }
  [[nodiscard]] bool needs_vertex_forces() const override { return true; }
  void save_state(StateWriter& out) const override;
  void load_state(StateReader& in) override;
  [[nodiscard]] VertexId focus() const { return focus_; }  ///< kInvalidId: none
  /// Breadth-first depth of each vertex advanced by the last step (-1: not advanced).
  [[nodiscard]] const std::vector<int>& last_depths() const { return depth_; }
  /// Sub-steps for a vertex at depth s: ceil(I / 2^s) for s <= s_max, else 0.
  [[nodiscard]] int iterations_at_depth(int depth) const;
  /// Breadth-first sweeps the last step was split into (1 while dt is within the limit).
  [[nodiscard]] int last_sweeps() const { return last_sweeps_; }
  /// Fraction of the explicit stability limit one sweep may cover (default 0.9).
  void set_sweep_fraction(double fraction) { sweep_fraction_ = fraction; }

 private:
  void sweep(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t, double dt);
  double sweep_fraction_ = 0.9;
  int last_sweeps_ = 1;
  HierarchicalOptions options_;
  VertexId focus_ = kInvalidId;
  std::vector<double> stamp_;  ///< time (s) up to which each vertex has been advanced
  std::vector<int> depth_;
  std::vector<VertexId> order_;
};

/// Backward Euler's Newton steps and linear solver (scene key `integrator`).
struct BackwardEulerOptions {
  /// Newton steps per time step; 1 is the linearised step of Baraff and Witkin (1998).
  int newton_steps = 1;
  LinearSolverOptions solver;  ///< how each Newton step's system is solved
};

/// Backward (implicit) Euler: M (v1 - v0) = dt f(x0 + dt v1, v1), solved by Newton's method on
/// the linearised force (the first step is Baraff and Witkin's linearised step), each linear
/// system by preconditioned conjugate gradients warm-started from the last step's solution, or
/// by a direct factorisation. Stable at any step size; damps high frequencies.
class BackwardEuler final : public Integrator {
 public:
  /// Steps as `options` say.
  explicit BackwardEuler(const BackwardEulerOptions& options = {});
  [[nodiscard]] std::string name() const override { return "backward-euler"; }
  [[nodiscard]] bool implicit() const override { return true; }
  [[nodiscard]] bool needs_linearization() const override { return true; }
  [[nodiscard]] double stability_limit(const DynamicSystem& system) const override;
  void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
            double dt) override;
  void save_state(StateWriter& out) const override;
  void load_state(StateReader& in) override;

 private:
  BackwardEulerOptions options_;
  LinearizedSystemSolver solver_;
  std::vector<Vec3> x_trial_, v_trial_, force_, rhs_, delta_;
  /// The first Newton step's velocity changes of the last steps, newest first.
  std::vector<std::vector<Vec3>> history_;
  std::vector<char> constrained_;
};

/// Static equilibrium's Newton iterations, tolerance and linear solver.
struct StaticOptions {
  int max_iterations = 50;  ///< Newton iterations per solve
  /// Converged when the free vertices' force residual falls below this fraction of the load
  /// (gravity plus point forces, or the first residual when only displacements load the body).
  double tolerance = 1e-8;
  /// Factorises up to auto_direct_limit() unknowns (exact Newton steps, robust on slender
  /// bodies), CG above.
  LinearSolverOptions solver = {.type = LinearSolverType::kAuto};
};

/// Static equilibrium f(x) = 0 by Newton's method with a backtracking line search on the
/// potential energy. As an integrator, a step solves for equilibrium at the step's end time
/// (prescribed displacements then) and sets velocities to zero: frames are a quasi-static
/// sequence.
class StaticEquilibrium final : public Integrator {
 public:
  /// Solves as `options` say.
  explicit StaticEquilibrium(const StaticOptions& options = {});
  [[nodiscard]] std::string name() const override { return "static"; }
  [[nodiscard]] bool implicit() const override { return true; }
  [[nodiscard]] bool needs_linearization() const override { return true; }
  [[nodiscard]] double stability_limit(const DynamicSystem& system) const override;
  void step(DynamicSystem& system, std::span<Vec3> x, std::span<Vec3> v, double t,
            double dt) override;
  /// Solves at time t; returns whether the tolerance was met.
  bool solve(DynamicSystem& system, std::span<Vec3> x, double t);
  [[nodiscard]] int last_iterations() const { return last_iterations_; }  ///< Newton's, last solve
  [[nodiscard]] double last_residual() const { return last_residual_; }   ///< relative, last solve
  /// The last solve's linear solves: CG iterations summed (one per factorisation), whether
  /// they were factorised, and their time (s) building preconditioners or factors.
  [[nodiscard]] long long last_linear_iterations() const { return last_linear_iterations_; }
  [[nodiscard]] bool last_solve_direct() const { return last_solve_direct_; }  ///< factorised
  /// Time building preconditioners or factors in the last solve (s).
  [[nodiscard]] double last_factorization_seconds() const { return last_factorization_seconds_; }

 private:
  StaticOptions options_;
  LinearizedSystemSolver solver_;
  std::vector<Vec3> force_, step_, trial_, zero_;
  std::vector<char> constrained_;
  int last_iterations_ = 0;
  double last_residual_ = 0.0;
  long long last_linear_iterations_ = 0;
  bool last_solve_direct_ = false;
  double last_factorization_seconds_ = 0.0;
};

/// Largest stable step (s) of an explicit scheme for the system's highest frequency: about
/// 2 / omega (Euler) and 2.8 / omega (RK4).
[[nodiscard]] double explicit_stability_limit(const DynamicSystem& system,
                                              const std::string& scheme);

}  // namespace incise
