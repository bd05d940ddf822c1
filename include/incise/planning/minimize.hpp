#pragma once
// Unconstrained minimisation of a smooth function of point positions over the points marked
// free (the others stay where they are): the seed's nonlinear conjugate gradients
// (Polak-Ribiere+, restarted when not a descent direction, with a strong-Wolfe line search)
// and limited-memory BFGS (liblbfgs from Debian, More-Thuente line search), which the seed
// did not have. Both accept only steps that decrease the function: the value is monotone.

#include <functional>
#include <span>
#include <string>
#include <vector>

#include "incise/core/types.hpp"

namespace incise::planning {

/// kNewton (newton.hpp) minimises the tissue's energy with its Hessian; the others any Objective.
enum class Minimizer { kNonlinearCG, kLbfgs, kNewton };

/// "cg" / "lbfgs" / "newton"; throws InputError naming the known ones.
[[nodiscard]] Minimizer parse_minimizer(const std::string& name);
[[nodiscard]] std::string to_string(Minimizer minimizer);

/// How minimize() minimises (plan key `solver`).
struct MinimizeOptions {
  Minimizer method = Minimizer::kLbfgs;  ///< the method
  /// Converged when the largest free gradient entry (per point, Euclidean) is at most this
  /// (units of the gradient: N for energies in J over positions in m).
  double gradient_tolerance = 1e-9;
  int max_iterations = 20000;  ///< iterations (Newton steps) before it stops unconverged
  int lbfgs_memory = 8;        ///< L-BFGS's pairs of earlier steps
};

/// What one Newton step did (MinimizeResult::newton_steps; the plan report's `newton.steps`).
struct NewtonStep {
  /// Conjugate gradient iterations with the factor in hand (lagged solves, on the exact
  /// Hessian and then its convex form).
  int lagged_iterations = 0;
  int lagged_budget = 0;     ///< the most each of those solves was allowed (0: no factor)
  bool lagged = false;       ///< solved with the factor in hand
  bool convexified = false;  ///< on the Hessian's convex form (the exact one was indefinite)
  bool factorized = false;   ///< a new factorisation
  double step_length = 0.0;  ///< the accepted fraction of the Newton step (0: none accepted)
  double gradient = 0.0;     ///< the largest free point's gradient after the step (N)
};

/// What a minimisation did (the plan report's `prediction`).
struct MinimizeResult {
  bool converged = false;         ///< the gradient tolerance was met
  int iterations = 0;             ///< iterations (Newton steps)
  int evaluations = 0;            ///< function-and-gradient evaluations
  double initial_value = 0.0;     ///< the function's value at the start (J for energies)
  double final_value = 0.0;       ///< at the end
  double initial_gradient = 0.0;  ///< largest free gradient entry at the start
  double final_gradient = 0.0;    ///< at the end
  bool monotone = true;           ///< every accepted iterate decreased the value
  int factorizations = 0;         ///< Newton: sparse Cholesky factorisations
  int lagged_steps = 0;           ///< Newton: steps solved with an earlier factorisation (and CG)
  int convexified_steps = 0;  ///< Newton: steps on the convexified Hessian (indefinite exact one)
  /// Newton: analyses of the Hessian's pattern (0 when one was in hand: an earlier prediction's,
  /// or the equilibrium's through NewtonWorkspace::lend_factorization).
  int pattern_analyses = 0;
  /// Newton: factorisations of an exact Hessian that found it indefinite (each step then
  /// factorised its convex form instead).
  int indefinite_attempts = 0;
  /// Newton: where the time went (s): Hessian assembly, factorisations, solves with a factor
  /// (lagged conjugate gradients included), energy evaluations of the line search.
  double assembly_seconds = 0.0;
  double factorization_seconds = 0.0;  ///< s
  double solve_seconds = 0.0;          ///< s
  double line_search_seconds = 0.0;    ///< s
  double seconds = 0.0;                ///< s in all
  std::string message;                 ///< why it stopped
  /// Newton: each step tried, in order (one more than `iterations` when the last found no
  /// decrease and ended the minimisation).
  std::vector<NewtonStep> newton_steps;
};

/// The largest Euclidean norm of a point's entry over the points marked free: the measure of
/// convergence of every minimiser here (and the largest free force, for a force field).
[[nodiscard]] double largest_free(std::span<const Vec3> g, std::span<const char> free);

/// Value and, into `gradient` (every point; entries of fixed points are ignored), gradient.
using Objective = std::function<double(std::span<const Vec3> x, std::span<Vec3> gradient)>;
/// Called after each iteration with its number and the largest free gradient entry.
using MinimizeProgress = std::function<void(int iteration, double gradient)>;

MinimizeResult minimize(const Objective& objective, std::span<Vec3> x, std::span<const char> free,
                        const MinimizeOptions& options, const MinimizeProgress& progress = {});

}  // namespace incise::planning
