#include "incise/planning/newton.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "incise/core/error.hpp"
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
/// A shift at least this large: the exact Hessian was indefinite a step ago (1e-3, shrunk to
/// 3e-4 by the step between), or more than once lately.
constexpr double kRecentlyIndefiniteShift = 1e-4;
/// A lagged factorisation's conjugate gradients, to this relative residual (an inexact Newton
/// step: the line search and the next step correct the rest): at least kLeastLaggedIterations,
/// at most as many as cost half a new factorisation's operations (lagged_iterations), never
/// more than kMostLaggedIterations.
constexpr int kLeastLaggedIterations = 6;
constexpr int kMostLaggedIterations = 40;
constexpr double kLaggedTolerance = 1e-2;
/// A lagged solve goes on until no residual entry is above kFinalStepMargin times the gradient
/// tolerance where that is at least kReachableGoal times the largest gradient (a few more
/// iterations than kLaggedTolerance takes). A point's residual is at most sqrt(3) times its
/// largest entry: 0.87 times the tolerance, the rest for Newton's quadratic term.
constexpr double kFinalStepMargin = 0.5;
constexpr double kReachableGoal = 1e-4;
/// The step with a new single-precision factor, refined by its conjugate gradients to this
/// relative residual (a direct solve's accuracy, for Newton's fast convergence near the
/// minimum), within kRefinedIterations; else the matrix is factorised in double.
constexpr double kRefinedTolerance = 1e-10;
constexpr int kRefinedIterations = 30;

/// How many preconditioned conjugate gradient iterations cost half of a factorisation. An
/// iteration is a solve with the factor (4 flops per factor nonzero; memory-bound triangular
/// sweeps, in single precision, on both cores) and a product with the matrix (4 flops per
/// stored nonzero), counted kSolveSlowdown times against the factorisation's BLAS-3 flops.
/// Measured (session 43, 2 cores): a factorisation costs 58-83 iterations (10k points 0.124 s
/// against 1.5 ms, headsq 0.156 s against 2.7 ms, 25k 0.33 s against 5.2 ms, 59k 0.94 s
/// against 14 ms), which the count matches at a slowdown of 0.4-1.5. The slowdown was 5 (for
/// double-precision solves, before the single-precision sweeps): the predictions from the scan
/// of 10k-59k points then factorised once more than they needed (10k points 0.43 -> 0.32 s,
/// 25k 1.74-1.91 -> 1.44-1.47 s, 59k 4.95-5.1 -> 4.49-4.64 s at 2; headsq the same steps),
/// and nudges took the same steps either way. At 1 (the measured rate) the lagged solves on an
/// ageing factor cost more than the factorisations they save (25k-59k points 6-20 % slower
/// than at 2): a fresh factor also serves the steps after it, which the count does not weigh.
/// Counted in operations, not timed, so that a prediction takes the same steps on any machine
/// and under any load (the planning viewer's replays rely on it). The factorisations are now in
/// single precision, 3-4x faster than CHOLMOD's in double for the same flops (session 49), but
/// a budget of a quarter or a sixth of them instead of half took the same time or more (10k-59k
/// points: one more factorisation, the same steps): half stays.
int lagged_iterations(const DirectFactorization& factor,
                      const DirectFactorization::SparseMatrix& matrix) {
  constexpr double kSolveSlowdown = 2.0;
  const DirectFactorization::Cost cost = factor.cost();
  const double per_iteration = kSolveSlowdown * 4.0 * cost.nonzeros +
                               kSolveSlowdown * 4.0 * static_cast<double>(matrix.nonZeros());
  if (!(per_iteration > 0.0) || !(cost.flops > 0.0)) {
    return kLeastLaggedIterations;
  }
  return static_cast<int>(std::clamp(0.5 * cost.flops / per_iteration,
                                     static_cast<double>(kLeastLaggedIterations),
                                     static_cast<double>(kMostLaggedIterations)));
}

/// The Hessian of the energy over the free points; with `convex`, its positive semi-definite
/// form: the transverse term of compressed springs (negative: they buckle) left out, the
/// tetrahedra's convex form, the volume term's curvature left out.
void assemble_hessian(const LayeredTissue& tissue,
                      std::span<const PointBlockMatrix::Target> targets, std::span<const Vec3> x,
                      bool convex, PointBlockMatrix& hessian) {
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
  add_prism_hessians(
      tissue, targets, x,
      {.tets = tissue.elasticity == TissueElasticity::kContinuum, .volume = true, .convex = convex},
      hessian);
}

enum class LaggedSolve {
  kSolved,
  kNegativeCurvature,  ///< the matrix is not positive definite
  kNotConverged,       ///< too far from the factorised one
};

/// Conjugate gradients on `matrix` (lower triangle stored) preconditioned by `factor` (of an
/// earlier, nearby matrix). Not solved, leaving `x` unusable, on negative curvature or when the
/// relative residual is not below kLaggedTolerance within lagged_iterations(): then the matrix
/// has moved too far from the factorised one and is factorised itself (negative curvature says
/// beforehand that a Cholesky factorisation of it would fail). With `tolerance` and
/// `most_iterations` (> 0), to that residual within that many: the refinement of a step with
/// a new single-precision factor of the matrix itself, or a short lagged solve with an ageing
/// factor. `iterations_used`, if given, receives the iterations it took; with a `goal` (N, the
/// largest residual entry wanted: a step within reach of the gradient tolerance),
/// `iterations_to_tolerance` those that reached `tolerance` (0 if it was not).
LaggedSolve lagged_solve(const DirectFactorization::SparseMatrix& matrix,
                         DirectFactorization& factor, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                         double tolerance = kLaggedTolerance, int most_iterations = 0,
                         int* iterations_used = nullptr, double goal = 0.0,
                         int* iterations_to_tolerance = nullptr) {
  if (iterations_used != nullptr) {
    *iterations_used = 0;
  }
  if (iterations_to_tolerance != nullptr) {
    *iterations_to_tolerance = 0;
  }
  const auto a = matrix.selfadjointView<Eigen::Lower>();
  // The factor preconditions in single precision (half the bytes to read, on worker threads):
  // its steps are wanted to kLaggedTolerance, not to sixteen digits.
  const auto precondition = [&factor](const Eigen::VectorXd& v) {
    return factor.solve_single_precision(v);
  };
  x = precondition(b);
  Eigen::VectorXd r = b - a * x;
  const double b_norm = b.norm();
  if (!(b_norm > 0.0)) {
    return LaggedSolve::kNotConverged;
  }
  const auto finite = [&x] {
    return x.allFinite() ? LaggedSolve::kSolved : LaggedSolve::kNotConverged;
  };
  // The residual is checked as soon as it is updated, before the next solve with the factor
  // (the costliest part of an iteration: a converged step needs none after its last update).
  //
  // With a `goal` (> 0), solved as soon as no residual entry is above it; past the tolerance,
  // the iterations go on toward it for at most as many again as the tolerance took (and within
  // the budget): solved either way.
  int reached_tolerance = -1;  // the iterations the tolerance took, once it was reached
  const auto converged = [&](int iterations) {
    const bool at_goal = goal > 0.0 && r.lpNorm<Eigen::Infinity>() <= goal;
    if (reached_tolerance < 0) {
      if (r.norm() > tolerance * b_norm) {
        return at_goal;
      }
      reached_tolerance = iterations;
      if (iterations_to_tolerance != nullptr) {
        *iterations_to_tolerance = iterations;
      }
    }
    return !(goal > 0.0) || at_goal || iterations >= 2 * reached_tolerance;
  };
  if (converged(0)) {
    return finite();
  }
  Eigen::VectorXd z = precondition(r);
  Eigen::VectorXd p = z;
  double rz = r.dot(z);
  const int most = most_iterations > 0 ? most_iterations : lagged_iterations(factor, matrix);
  for (int iteration = 0; iteration < most; ++iteration) {
    if (iterations_used != nullptr) {
      *iterations_used = iteration + 1;
    }
    const Eigen::VectorXd ap = a * p;
    const double curvature = p.dot(ap);
    if (!(curvature > 0.0)) {
      return reached_tolerance >= 0 ? finite() : LaggedSolve::kNegativeCurvature;
    }
    const double step = rz / curvature;
    x += step * p;
    r -= step * ap;
    if (converged(iteration + 1)) {
      return finite();
    }
    z = precondition(r);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return reached_tolerance >= 0 ? finite() : LaggedSolve::kNotConverged;
}

}  // namespace

struct NewtonWorkspace::Data {
  const LayeredTissue* tissue = nullptr;
  std::size_t springs = 0;
  std::size_t prisms = 0;
  std::vector<char> free;
  std::vector<int> row;  ///< each free point's first row, -1 for the others
  int rows = 0;
  CouplingPattern pattern;
  std::optional<PointBlockMatrix> hessian;
  std::vector<PointBlockMatrix::Target> prism_targets;  ///< where the prisms' blocks go in it
  bool have_factor = false;
  /// The last minimisation's first exact Hessian was indefinite: the next one, a nudge like
  /// it, starts with the convex form instead of finding that out again (an assembly and a few
  /// solves with the factor; the step taken is the same).
  bool first_step_indefinite = false;
  /// A lagged solve with the factor in hand took more than half its budget: the Hessian has
  /// moved far from the factorised one, and the next lagged solves get kLeastLaggedIterations.
  bool factor_ageing = false;
};

NewtonWorkspace::NewtonWorkspace() = default;
NewtonWorkspace::~NewtonWorkspace() = default;
NewtonWorkspace::NewtonWorkspace(NewtonWorkspace&&) noexcept = default;
NewtonWorkspace& NewtonWorkspace::operator=(NewtonWorkspace&&) noexcept = default;

bool NewtonWorkspace::has_factor() const {
  return data_ && data_->have_factor;
}

DirectFactorization& NewtonWorkspace::factorization() {
  if (!factorization_) {
    factorization_ = std::make_unique<DirectFactorization>();
  }
  return *factorization_;
}

DirectFactorization& NewtonWorkspace::lend_factorization() {
  forget_factor();
  return factorization();
}

void NewtonWorkspace::forget_factor() {
  if (data_) {
    data_->have_factor = false;
    data_->factor_ageing = false;
    data_->first_step_indefinite = false;
  }
}

NewtonWorkspace::Data& NewtonWorkspace::data_for(const LayeredTissue& tissue,
                                                 std::span<const char> free) {
  // (free holds a flag per point: equal flags mean the same point count too)
  const bool same = data_ && data_->tissue == &tissue && data_->springs == tissue.springs.size() &&
                    data_->prisms == tissue.prisms.size() &&
                    std::equal(free.begin(), free.end(), data_->free.begin(), data_->free.end());
  if (same) {
    return *data_;
  }
  data_ = std::make_unique<Data>();
  Data& d = *data_;
  d.tissue = &tissue;
  d.springs = tissue.springs.size();
  d.prisms = tissue.prisms.size();
  d.free.assign(free.begin(), free.end());
  d.row.assign(free.size(), -1);
  for (std::size_t i = 0; i < free.size(); ++i) {
    if (free[i] != 0) {
      d.row[i] = d.rows;
      d.rows += 3;
    }
  }
  d.pattern = coupling_pattern(tissue);
  d.hessian.emplace(d.row, d.rows, d.pattern.pairs);
  d.prism_targets = prism_targets(tissue, d.pattern, *d.hessian);
  return d;
}

void NewtonWorkspace::factorize_at(const TissueEnergy& energy, std::span<const Vec3> x,
                                   std::span<const char> free) {
  const LayeredTissue& tissue = energy.tissue();
  if (x.size() != tissue.point_count() || free.size() != tissue.point_count()) {
    throw InputError("NewtonWorkspace: positions, free flags and the tissue differ in size");
  }
  Data& d = data_for(tissue, free);
  d.have_factor = false;
  if (d.rows == 0) {
    return;
  }
  // For the lagged solves only: in single precision where floats suffice.
  assemble_hessian(tissue, d.prism_targets, x, false, *d.hessian);
  if (!factorization().factorize_preconditioner(d.hessian->matrix(), true)) {
    assemble_hessian(tissue, d.prism_targets, x, true, *d.hessian);
    d.hessian->damp_diagonal(1e-12, 0.0);
    if (!factorization().factorize_preconditioner(d.hessian->matrix(), false)) {
      throw InputError(
          "Newton's prediction: the tissue's stiffness matrix cannot be factorised "
          "(a free point held by no spring?)");
    }
  }
  d.have_factor = true;
  d.factor_ageing = false;
}

MinimizeResult minimize_newton(const TissueEnergy& energy, std::span<Vec3> x,
                               std::span<const char> free, const MinimizeOptions& options,
                               const MinimizeProgress& progress, NewtonWorkspace* workspace) {
  const auto start = Clock::now();
  const LayeredTissue& tissue = energy.tissue();
  const std::size_t n = x.size();
  if (n != free.size() || n != tissue.point_count()) {
    throw InputError("minimize_newton: positions, free flags and the tissue differ in size");
  }
  MinimizeResult result;
  NewtonWorkspace own;
  NewtonWorkspace& space = workspace != nullptr ? *workspace : own;
  const bool start_convex = std::exchange(space.start_convex_, false);
  NewtonWorkspace::Data& data = space.data_for(tissue, free);
  const std::vector<int>& row = data.row;
  const int rows = data.rows;
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

  const std::vector<PointBlockMatrix::Target>& targets = data.prism_targets;
  PointBlockMatrix& hessian = *data.hessian;
  DirectFactorization& factorization = space.factorization();
  const int analyses_before = factorization.analyses();
  bool& have_factor = data.have_factor;  // a factor of an earlier, nearby Hessian
  double damping = 0.0;                  // relative, grown only when a step fails
  double shift = 0.0;                    // relative, after an indefinite exact Hessian
  int non_descent_steps = 0;
  double best_gradient = gradient;
  int steps_since_best = 0;
  std::vector<Vec3> trial(x.begin(), x.end());
  std::vector<Vec3> trial_gradient(n);
  Eigen::VectorXd rhs(rows);
  result.message = "iteration limit";
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    NewtonStep& record = result.newton_steps.emplace_back();
    for (std::size_t i = 0; i < n; ++i) {
      if (row[i] >= 0) {
        rhs.segment<3>(row[i]) = -g[i];
      }
    }
    // The exact Hessian, shifted by a multiple of its diagonal after indefinite ones
    // (Levenberg-Marquardt; the shift decays as steps succeed).
    auto mark = Clock::now();
    const auto lap = [&mark](double& seconds) {
      const auto now = Clock::now();
      seconds += std::chrono::duration<double>(now - mark).count();
      mark = now;
    };
    // A step whose gradient is within reach of the tolerance is solved toward it: the linear
    // residual left is the gradient after the step but for Newton's quadratic term (smaller
    // here), and a few more iterations can spare a whole step (an assembly, an evaluation and
    // the solve). Its Hessian is not shifted: a shift left from an indefinite Hessian some steps
    // ago would leave shift * diagonal * step in the gradient (the 59k-point phantom's sixth
    // step: 6.9e-6 N left of it against a tolerance of 3.1e-6 N, and a seventh step).
    const double goal = kFinalStepMargin * options.gradient_tolerance;
    const bool within_reach = goal >= kReachableGoal * gradient;
    // A warm start whose last first step met an indefinite Hessian goes to the convex form at
    // once (below, as if the exact one had just shown negative curvature).
    // So does a start the caller knows to be indefinite (without a factor, it is factorised
    // in its convex form below, as after a failed attempt on the exact one).
    const bool known_indefinite =
        iteration == 0 && (start_convex || (have_factor && data.first_step_indefinite));
    // An ageing factor right after an indefinite Hessian: its short lagged solve on the exact
    // Hessian failed wherever seen (the 59k-point phantom's third step, 0.15 s; a sphere model
    // pushed 2.4 cm and turned 0.6 rad), and the convex form is factorised next either way
    // (below): it is, without the exact Hessian's assembly and solve.
    const bool straight_to_convex = have_factor && data.factor_ageing && !within_reach &&
                                    shift >= kRecentlyIndefiniteShift && !known_indefinite;
    if (!known_indefinite && !straight_to_convex) {
      assemble_hessian(tissue, targets, x, false, hessian);
      hessian.damp_diagonal(damping + (within_reach ? 0.0 : shift), 0.0);
      lap(result.assembly_seconds);
    }
    Eigen::VectorXd step;
    // First, conjugate gradients on it preconditioned by the last factorisation: a few solves
    // with a factor already paid for, instead of a new factorisation, while the Hessian has not
    // moved far from the one factorised.
    //
    // A factor whose last lagged solve needed most of its budget is ageing: the iterates move
    // on and the next Hessian is farther from the factorised one, so the next solve gets a
    // short budget before a new factorisation. (The 59k-point phantom's third step spent 25
    // iterations, 0.45 s, failing to reach the tolerance before factorising: 2.76-2.91 ->
    // 2.49-2.56 s for its prediction, the same steps after it.)
    const int full_budget = have_factor ? lagged_iterations(factorization, hessian.matrix()) : 0;
    const int budget = data.factor_ageing ? kLeastLaggedIterations : full_budget;
    int used = 0;          // iterations of the last lagged solve
    int to_tolerance = 0;  // of the solve taken, those that reached kLaggedTolerance
    record.lagged_budget = have_factor && !straight_to_convex ? budget : 0;
    const LaggedSolve outcome =
        known_indefinite ? LaggedSolve::kNegativeCurvature
        : have_factor && !straight_to_convex
            ? lagged_solve(hessian.matrix(), factorization, rhs, step, kLaggedTolerance, budget,
                           &used, within_reach ? goal : 0.0, &to_tolerance)
            : LaggedSolve::kNotConverged;
    if (iteration == 0 && !start_convex) {  // what the exact Hessian showed, if it was tried
      data.first_step_indefinite = outcome == LaggedSolve::kNegativeCurvature;
    }
    bool lagged = outcome == LaggedSolve::kSolved && rhs.dot(step) > 0.0;  // descent
    record.lagged_iterations += used;
    lap(result.solve_seconds);
    // The Hessian replaced by its convex form (positive semi-definite by construction), and the
    // shift grown for the exact ones to come.
    bool convexified = false;
    const auto convexify = [&] {
      convexified = true;
      shift = shift == 0.0 ? kFirstShift : shift * 10.0;
      ++result.convexified_steps;
      assemble_hessian(tissue, targets, x, true, hessian);
      hessian.damp_diagonal(std::max(damping, 1e-12), 0.0);
      lap(result.assembly_seconds);
    };
    if (!lagged && outcome == LaggedSolve::kNegativeCurvature) {
      // The exact Hessian is indefinite (a Cholesky factorisation of it would fail): its convex
      // form, solved with the factor in hand if it still preconditions it well (the steps of
      // interactive nudges: each starts indefinite and is one factorisation cheaper so).
      convexify();
      lagged = have_factor &&
               lagged_solve(hessian.matrix(), factorization, rhs, step, kLaggedTolerance, budget,
                            &used) == LaggedSolve::kSolved &&
               rhs.dot(step) > 0.0;
      to_tolerance = used;  // (no goal: solved when the tolerance is reached)
      record.lagged_iterations += used;
      lap(result.solve_seconds);
    }
    // A new factorisation in single precision, its step refined by conjugate gradients in
    // double; in double (CHOLMOD, solved directly) where floats do not suffice: a matrix not
    // positive definite in floats, or a step the refinement does not reach. `solved`: the
    // step is taken.
    bool solved = false;
    const auto factorize_fresh = [&](bool positive_only) {
      const auto& matrix = hessian.matrix();
      const bool single = factorization.factorize_single_precision(matrix);
      lap(result.factorization_seconds);
      if (single) {
        solved = lagged_solve(matrix, factorization, rhs, step, kRefinedTolerance,
                              kRefinedIterations) == LaggedSolve::kSolved;
        lap(result.solve_seconds);
        if (solved) {
          return true;
        }
      } else if (positive_only) {
        return false;  // not positive definite (in floats): the convex form is factorised next
      }
      const bool factorized = positive_only ? factorization.factorize_positive_definite(matrix)
                                            : factorization.factorize(matrix);
      lap(result.factorization_seconds);
      return factorized;
    };
    record.lagged = lagged;
    if (lagged) {
      ++result.lagged_steps;
      data.factor_ageing = data.factor_ageing || 2 * to_tolerance > full_budget;
    } else {
      // A factorisation of the exact Hessian where it is positive definite: fast convergence
      // near the minimum. Else of its convex part, which always gives a descent direction.
      //
      // Right after an indefinite exact Hessian (its shift still at least
      // kRecentlyIndefiniteShift), the exact one is not factorised after its lagged solve
      // failed, its convex form is: in floats that attempt failed on every plan tried (0.12 s lost
      // at 59k points, a third of a factorisation), and the convex form's step served as well where
      // it would not have (a sphere model pushed 12-20 mm: the same steps or fewer).
      const bool recently_indefinite = shift >= kRecentlyIndefiniteShift;
      if (recently_indefinite && !convexified) {
        convexify();
      }
      bool factorized = !convexified && factorize_fresh(true);
      if (!factorized && !convexified) {
        ++result.indefinite_attempts;
      }
      if (!factorized) {
        if (!convexified) {
          convexify();
        }
        factorized = factorize_fresh(false);
      }
      have_factor = factorized;
      data.factor_ageing = false;
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
      record.factorized = true;
      if (!solved) {
        step = factorization.solve(rhs);
        lap(result.solve_seconds);
      }
    }
    record.convexified = convexified;
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
        record.step_length = alpha;
        value = trial_value;
        std::copy(trial.begin(), trial.end(), x.begin());
        std::swap(g, trial_gradient);
      }
    }
    lap(result.line_search_seconds);
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
    record.gradient = gradient;
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
  result.pattern_analyses = factorization.analyses() - analyses_before;
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace incise::planning
