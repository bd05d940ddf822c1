#pragma once
// Newton's method for the prediction's energy F_E + F_V + F_G (which the seed did not have):
// each step solves H p = -g over the free points with a sparse Cholesky factorisation (CHOLMOD
// where built with it; the pattern is analysed once), then a backtracking line search on the
// energy. H is the exact Hessian (springs, and the volume term with its curvature: the prism
// volume is cubic, so its Hessian comes exactly from central differences of the gradient),
// shifted by a decaying multiple of its diagonal after an indefinite one (Levenberg-Marquardt);
// when it is still not positive definite (compressed springs buckle), its convex form is used:
// per spring the transverse term only when stretched, per prism the Gauss-Newton part. Near the
// minimum the steps are exact Newton steps and converge quadratically.

#include <span>

#include "incise/planning/minimize.hpp"
#include "incise/planning/tissue_energy.hpp"

namespace incise::planning {

/// Minimises energy.energy() over the points marked free (options.gradient_tolerance, N;
/// options.max_iterations Newton steps). Every accepted step decreases the energy.
MinimizeResult minimize_newton(const TissueEnergy& energy, std::span<Vec3> x,
                               std::span<const char> free, const MinimizeOptions& options,
                               const MinimizeProgress& progress = {});

}  // namespace incise::planning
