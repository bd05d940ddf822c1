#include "incise/planning/minimize.hpp"

#include <lbfgs.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include "incise/core/error.hpp"

namespace incise::planning {

Minimizer parse_minimizer(const std::string& name) {
  if (name == "cg") {
    return Minimizer::kNonlinearCG;
  }
  if (name == "lbfgs") {
    return Minimizer::kLbfgs;
  }
  if (name == "newton") {
    return Minimizer::kNewton;
  }
  throw InputError("unknown minimiser '" + name + "' (known: newton, lbfgs, cg)");
}

std::string to_string(Minimizer minimizer) {
  switch (minimizer) {
    case Minimizer::kNonlinearCG:
      return "cg";
    case Minimizer::kLbfgs:
      return "lbfgs";
    case Minimizer::kNewton:
      return "newton";
  }
  return "?";
}

double largest_free(std::span<const Vec3> g, std::span<const char> free) {
  double largest = 0.0;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (free[i] != 0) {
      largest = std::max(largest, g[i].norm());
    }
  }
  return largest;
}

namespace {

using Clock = std::chrono::steady_clock;

double free_dot(std::span<const Vec3> a, std::span<const Vec3> b, std::span<const char> free) {
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (free[i] != 0) {
      sum += a[i].dot(b[i]);
    }
  }
  return sum;
}

/// Nonlinear CG: Polak-Ribiere+ directions, a strong-Wolfe line search (Nocedal and Wright,
/// algorithms 3.5 and 3.6, with cubic interpolation in the zoom), restarts when a direction
/// does not descend. Written here: the Debian libraries with nonlinear CG (GSL) use a line
/// minimisation without the Wolfe conditions, which stalls on stiff problems like this one.
class ConjugateGradients {
 public:
  ConjugateGradients(const Objective& objective, std::span<Vec3> x, std::span<const char> free,
                     MinimizeResult& result)
      : objective_(objective),
        x_(x),
        free_(free),
        result_(result),
        trial_(x.size()),
        trial_gradient_(x.size()) {}

  double evaluate(std::span<const Vec3> at, std::span<Vec3> gradient) {
    ++result_.evaluations;
    const double value = objective_(at, gradient);
    for (std::size_t i = 0; i < gradient.size(); ++i) {
      if (free_[i] == 0) {
        gradient[i].setZero();
      }
    }
    return value;
  }

  /// phi(alpha) = f(x + alpha p) and its slope, into trial_ / trial_gradient_.
  double phi(double alpha, std::span<const Vec3> p, double& slope) {
    for (std::size_t i = 0; i < x_.size(); ++i) {
      trial_[i] = free_[i] != 0 ? Vec3(x_[i] + alpha * p[i]) : x_[i];
    }
    const double value = evaluate(trial_, trial_gradient_);
    slope = free_dot(trial_gradient_, p, free_);
    trial_value_ = value;
    return value;
  }

  /// Returns the accepted step (0: none), leaving its point in trial_.
  double line_search(std::span<const Vec3> p, double value0, double slope0, double alpha1) {
    constexpr double c1 = 1e-4;
    constexpr double c2 = 0.1;
    double alpha_prev = 0.0;
    double value_prev = value0;
    double slope_prev = slope0;
    double alpha = alpha1;
    for (int i = 0; i < 30; ++i) {
      double slope = 0.0;
      const double value = phi(alpha, p, slope);
      if (!std::isfinite(value) || value > value0 + c1 * alpha * slope0 ||
          (i > 0 && value >= value_prev)) {
        return zoom(p, value0, slope0, alpha_prev, value_prev, slope_prev, alpha, value, slope);
      }
      if (std::abs(slope) <= -c2 * slope0) {
        return alpha;
      }
      if (slope >= 0.0) {
        return zoom(p, value0, slope0, alpha, value, slope, alpha_prev, value_prev, slope_prev);
      }
      alpha_prev = alpha;
      value_prev = value;
      slope_prev = slope;
      alpha *= 2.0;
    }
    return 0.0;
  }

  double zoom(std::span<const Vec3> p, double value0, double slope0, double lo, double value_lo,
              double slope_lo, double hi, double value_hi, double slope_hi) {
    constexpr double c1 = 1e-4;
    constexpr double c2 = 0.1;
    for (int i = 0; i < 40; ++i) {
      // Cubic interpolation between lo and hi, kept inside the middle of the bracket.
      double alpha = 0.5 * (lo + hi);
      if (std::isfinite(value_hi)) {
        const double d1 = slope_lo + slope_hi - 3.0 * (value_lo - value_hi) / (lo - hi);
        const double root = d1 * d1 - slope_lo * slope_hi;
        if (root >= 0.0) {
          const double d2 = std::copysign(std::sqrt(root), hi - lo);
          const double cubic =
              hi - (hi - lo) * (slope_hi + d2 - d1) / (slope_hi - slope_lo + 2.0 * d2);
          const double low = std::min(lo, hi);
          const double high = std::max(lo, hi);
          if (std::isfinite(cubic) && cubic > low + 0.1 * (high - low) &&
              cubic < high - 0.1 * (high - low)) {
            alpha = cubic;
          }
        }
      }
      double slope = 0.0;
      const double value = phi(alpha, p, slope);
      if (!std::isfinite(value) || value > value0 + c1 * alpha * slope0 || value >= value_lo) {
        hi = alpha;
        value_hi = value;
        slope_hi = slope;
      } else {
        if (std::abs(slope) <= -c2 * slope0) {
          return alpha;
        }
        if (slope * (hi - lo) >= 0.0) {
          hi = lo;
          value_hi = value_lo;
          slope_hi = slope_lo;
        }
        lo = alpha;
        value_lo = value;
        slope_lo = slope;
      }
      if (std::abs(hi - lo) <= 1e-14 * std::max(std::abs(lo), std::abs(hi))) {
        break;
      }
    }
    // The bracket collapsed: accept lo if it decreased the function (sufficient decrease holds
    // there by construction), else nothing.
    if (lo > 0.0) {
      double slope = 0.0;
      (void)phi(lo, p, slope);
      return lo;
    }
    return 0.0;
  }

  void run(const MinimizeOptions& options, const MinimizeProgress& progress) {
    const std::size_t n = x_.size();
    std::vector<Vec3> gradient(n), direction(n);
    double value = evaluate(x_, gradient);
    result_.initial_value = value;
    double largest = largest_free(gradient, free_);
    result_.initial_gradient = largest;
    for (std::size_t i = 0; i < n; ++i) {
      direction[i] = -gradient[i];
    }
    double gradient_squared = free_dot(gradient, gradient, free_);
    double previous_alpha = 0.0;
    double previous_slope = 0.0;
    while (true) {
      if (largest <= options.gradient_tolerance) {
        result_.converged = true;
        result_.message = "gradient below tolerance";
        break;
      }
      if (result_.iterations >= options.max_iterations) {
        result_.message = "iteration limit";
        break;
      }
      double slope = free_dot(gradient, direction, free_);
      if (!(slope < 0.0)) {
        for (std::size_t i = 0; i < n; ++i) {
          direction[i] = -gradient[i];
        }
        slope = -gradient_squared;
      }
      // First trial: the last step scaled by the change of slope (Nocedal and Wright, 3.60);
      // at the start, a step moving the largest entry by 0.1 mm.
      const double alpha1 = previous_alpha > 0.0
                                ? std::max(previous_alpha * previous_slope / slope, 1e-30)
                                : 1e-4 / std::max(largest, 1e-300);
      const double alpha = line_search(direction, value, slope, alpha1);
      if (!(alpha > 0.0)) {
        if (slope == -gradient_squared) {
          result_.message = "line search found no decrease (rounding floor)";
          break;
        }
        // Retry along steepest descent.
        for (std::size_t i = 0; i < n; ++i) {
          direction[i] = -gradient[i];
        }
        previous_alpha = 0.0;
        continue;
      }
      const double new_value = trial_value_;  // trial_ holds the accepted point
      if (new_value > value) {
        result_.monotone = false;
      }
      std::copy(trial_.begin(), trial_.end(), x_.begin());
      const double new_squared = free_dot(trial_gradient_, trial_gradient_, free_);
      const double mixed = free_dot(trial_gradient_, gradient, free_);
      const double beta = std::max(0.0, (new_squared - mixed) / gradient_squared);
      std::copy(trial_gradient_.begin(), trial_gradient_.end(), gradient.begin());
      for (std::size_t i = 0; i < n; ++i) {
        direction[i] = free_[i] != 0 ? Vec3(-gradient[i] + beta * direction[i]) : Vec3::Zero();
      }
      gradient_squared = new_squared;
      value = new_value;
      previous_alpha = alpha;
      previous_slope = slope;
      largest = largest_free(gradient, free_);
      ++result_.iterations;
      if (progress) {
        progress(result_.iterations, largest);
      }
    }
    result_.final_value = value;
    result_.final_gradient = largest;
  }

 private:
  const Objective& objective_;
  std::span<Vec3> x_;
  std::span<const char> free_;
  MinimizeResult& result_;
  std::vector<Vec3> trial_, trial_gradient_;
  double trial_value_ = 0.0;
};

struct LbfgsContext {
  const Objective* objective;
  std::span<Vec3> x;
  std::span<const char> free;
  std::vector<std::size_t> free_points;
  std::vector<Vec3> gradient;
  MinimizeResult* result;
  const MinimizeOptions* options;
  const MinimizeProgress* progress;
  double last_value = 0.0;
  double largest = 0.0;
};

void unpack(LbfgsContext& context, const lbfgsfloatval_t* values) {
  for (std::size_t k = 0; k < context.free_points.size(); ++k) {
    context.x[context.free_points[k]] = Vec3(values[3 * k], values[3 * k + 1], values[3 * k + 2]);
  }
}

lbfgsfloatval_t evaluate_lbfgs(void* instance, const lbfgsfloatval_t* values,
                               lbfgsfloatval_t* gradient, int /*n*/, lbfgsfloatval_t /*step*/) {
  auto& context = *static_cast<LbfgsContext*>(instance);
  unpack(context, values);
  ++context.result->evaluations;
  const double value = (*context.objective)(context.x, context.gradient);
  context.largest = 0.0;
  for (std::size_t k = 0; k < context.free_points.size(); ++k) {
    const Vec3& g = context.gradient[context.free_points[k]];
    gradient[3 * k] = g.x();
    gradient[3 * k + 1] = g.y();
    gradient[3 * k + 2] = g.z();
    context.largest = std::max(context.largest, g.norm());
  }
  return std::isfinite(value) ? value : std::numeric_limits<double>::max();
}

int progress_lbfgs(void* instance, const lbfgsfloatval_t* /*x*/, const lbfgsfloatval_t* /*g*/,
                   lbfgsfloatval_t value, lbfgsfloatval_t /*xnorm*/, lbfgsfloatval_t /*gnorm*/,
                   lbfgsfloatval_t /*step*/, int /*n*/, int iteration, int /*ls*/) {
  auto& context = *static_cast<LbfgsContext*>(instance);
  if (value > context.last_value) {
    context.result->monotone = false;
  }
  context.last_value = value;
  context.result->iterations = iteration;
  if (*context.progress) {
    (*context.progress)(iteration, context.largest);
  }
  // The largest gradient entry of the accepted point decides convergence (liblbfgs's own test
  // scales the norm by |x|, which depends on where the body sits).
  return context.largest <= context.options->gradient_tolerance ? 1 : 0;
}

void run_lbfgs(const Objective& objective, std::span<Vec3> x, std::span<const char> free,
               const MinimizeOptions& options, const MinimizeProgress& progress,
               MinimizeResult& result) {
  LbfgsContext context{&objective, x,        free,     {}, std::vector<Vec3>(x.size()),
                       &result,    &options, &progress};
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (free[i] != 0) {
      context.free_points.push_back(i);
    }
  }
  const int n = static_cast<int>(3 * context.free_points.size());
  // The start: value and gradient.
  result.initial_value = objective(x, context.gradient);
  ++result.evaluations;
  result.initial_gradient = largest_free(context.gradient, free);
  context.last_value = result.initial_value;
  context.largest = result.initial_gradient;
  if (n == 0 || result.initial_gradient <= options.gradient_tolerance) {
    result.converged = true;
    result.final_value = result.initial_value;
    result.final_gradient = result.initial_gradient;
    result.message = "gradient below tolerance";
    return;
  }
  lbfgsfloatval_t* values = lbfgs_malloc(n);
  if (values == nullptr) {
    throw InputError("out of memory for the L-BFGS state");
  }
  for (std::size_t k = 0; k < context.free_points.size(); ++k) {
    const Vec3& p = x[context.free_points[k]];
    values[3 * k] = p.x();
    values[3 * k + 1] = p.y();
    values[3 * k + 2] = p.z();
  }
  lbfgs_parameter_t parameters;
  lbfgs_parameter_init(&parameters);
  parameters.m = options.lbfgs_memory;
  parameters.epsilon = 0.0;  // convergence is decided in progress_lbfgs
  parameters.max_iterations = options.max_iterations;
  parameters.max_linesearch = 40;
  lbfgsfloatval_t final_value = 0.0;
  const int status =
      lbfgs(n, values, &final_value, evaluate_lbfgs, progress_lbfgs, &context, &parameters);
  // liblbfgs leaves the best point in `values`; evaluate there to leave x and the gradient.
  unpack(context, values);
  lbfgs_free(values);
  result.final_value = objective(x, context.gradient);
  ++result.evaluations;
  result.final_gradient = largest_free(context.gradient, free);
  result.converged = result.final_gradient <= options.gradient_tolerance;
  if (result.converged) {
    result.message = "gradient below tolerance";
  } else if (status == LBFGSERR_MAXIMUMITERATION) {
    result.message = "iteration limit";
  } else {
    result.message = "liblbfgs stopped with status " + std::to_string(status) +
                     " (line search found no decrease: the rounding floor)";
  }
}

}  // namespace

MinimizeResult minimize(const Objective& objective, std::span<Vec3> x, std::span<const char> free,
                        const MinimizeOptions& options, const MinimizeProgress& progress) {
  if (x.size() != free.size()) {
    throw InputError("minimize: positions and free flags differ in size");
  }
  if (options.method == Minimizer::kNewton) {
    throw InputError("minimize: Newton's method needs the tissue's Hessian (minimize_newton)");
  }
  MinimizeResult result;
  const auto start = Clock::now();
  if (options.method == Minimizer::kNonlinearCG) {
    ConjugateGradients solver(objective, x, free, result);
    solver.run(options, progress);
  } else {
    run_lbfgs(objective, x, free, options, progress, result);
  }
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace incise::planning
