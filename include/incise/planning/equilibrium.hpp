#pragma once
// Equilibrium initialisation (Teschner et al.): the scanned geometry must be a stable rest
// state although gravity pulls on every soft-tissue point and the skin is pre-strained. The
// rest lengths of the springs are changed as little as possible, in the least-squares sense of
// their relative change, so that the resulting force on every soft-tissue point vanishes; the load
// goes to the bone and boundary points, which are fixed. The skin's springs take part too (an
// irregular triangulation leaves in-plane forces under a uniform pre-strain that only they can
// balance); their mean pre-strain is reported. Gauss-Newton on the rest lengths: for Hooke's law
// one step is exact up to rounding, the nonlinear law takes a few; the steps are damped
// (Levenberg-Marquardt) so that points whose springs are nearly coplanar keep a residual instead of
// a huge change.

#include "incise/planning/layered_tissue.hpp"

namespace incise {
class DirectFactorization;
}

namespace incise::planning {

/// What balancing the scanned state did (the plan report's `equilibrium`).
struct EquilibriumReport {
  double residual_before = 0.0;          ///< N: largest resulting force on a soft-tissue point
  double residual_after = 0.0;           ///< N
  int iterations = 0;                    ///< Newton-type steps taken
  double largest_relative_change = 0.0;  ///< of a rest length (springs)
  double largest_rest_shift = 0.0;       ///< m: of a rest position (continuum)
  int limited_changes = 0;           ///< steps held to half a rest length (summed over iterations)
  double skin_prestrain_mean = 0.0;  ///< of the skin layer's springs, after
  Vec3 load_on_fixed_points = Vec3::Zero();  ///< N: sum of forces diverted to bone and boundary
};

/// initialise_equilibrium's default largest residual force (N) and step limit: what a plan
/// balances its scanned state to.
inline constexpr double kEquilibriumTolerance = 1e-9;
inline constexpr int kEquilibriumIterations = 60;

/// Springs: changes `tissue`'s rest lengths (each Gauss-Newton step by at most half of one);
/// throws InputError when the forces cannot be balanced (a rest length would have to fall below
/// 5 % of its scanned length). Continuum: changes its tetrahedra's rest shapes; throws
/// InputError when one would invert. A residual above the tolerance (N) after max_iterations is
/// reported, not thrown. With `factorization`, its steps factorise through it: a prediction's
/// Newton steps that factorise the same pattern next (NewtonWorkspace::lend_factorization) then
/// need no analysis of their own (0.4 s of a 59k-point model's prediction).
EquilibriumReport initialise_equilibrium(LayeredTissue& tissue, const Vec3& gravity,
                                         double tolerance = kEquilibriumTolerance,
                                         int max_iterations = kEquilibriumIterations,
                                         DirectFactorization* factorization = nullptr);

}  // namespace incise::planning
