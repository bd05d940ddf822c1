#pragma once
// Newton's method for the prediction's energy F_E + F_V + F_G (which the seed did not have):
// each step solves H p = -g over the free points with a sparse Cholesky factorisation (CHOLMOD
// where built with it; the pattern is analysed once), then a backtracking line search on the
// energy. H is kept positive definite by construction: per spring the stiffness along it plus
// the tension's transverse part only when the spring is stretched; per prism the Gauss-Newton
// part of the volume term, kappa / |V0| (grad V)(grad V)^T (the dropped curvature term is
// proportional to the volume change, which the volume term keeps small). Where the projection
// costs quadratic convergence, the steps still converge fast, in tens of factorisations where
// L-BFGS takes thousands of iterations.

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
