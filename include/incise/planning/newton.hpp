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

#include <memory>
#include <span>

#include "incise/planning/minimize.hpp"
#include "incise/planning/tissue_energy.hpp"

namespace incise {
class DirectFactorization;
}

namespace incise::planning {

/// What one Newton minimisation leaves for the next on the same tissue and free points: the
/// Hessian's pattern, analysed once, and the last factorisation, which preconditions the next
/// run's steps (conjugate gradients on the new Hessian), so that a prediction after a small
/// move needs no factorisation of its own. Rebuilt by itself when the tissue or the free points
/// differ. One owner; not for two threads at once.
class NewtonWorkspace {
 public:
  NewtonWorkspace();
  ~NewtonWorkspace();
  /// Takes the other's pattern and factor.
  NewtonWorkspace(NewtonWorkspace&&) noexcept;
  /// Takes the other's pattern and factor.
  NewtonWorkspace& operator=(NewtonWorkspace&&) noexcept;

  /// Factorises the Hessian at x (its convex form where the exact one is indefinite), so that
  /// the next minimisation from near x starts with a factor. Throws when neither factorises.
  void factorize_at(const TissueEnergy& energy, std::span<const Vec3> x,
                    std::span<const char> free);
  /// Whether a factor is in hand for the next minimisation.
  [[nodiscard]] bool has_factor() const;
  /// Drops the factor (the pattern and its analysis stay): the next minimisation takes the
  /// steps a fresh one would, to the last bit.
  void forget_factor();
  /// The factorisation its steps solve with, for another solve to use first (the equilibrium
  /// before the first prediction): an analysis of the pattern it leaves is kept, so that the
  /// minimisation need not make one. The factor in hand is dropped, as by forget_factor().
  [[nodiscard]] DirectFactorization& lend_factorization();
  /// The next minimisation takes its first step on the Hessian's convex form without trying
  /// the exact one: for a start the caller knows to be indefinite there (bone moved into the
  /// tissue from the scanned state), where the attempt costs an assembly and a failed
  /// factorisation (0.3 s at 59k points) and ends in the same step.
  void start_convex() { start_convex_ = true; }

  struct Data;  ///< newton.cpp's

 private:
  friend MinimizeResult minimize_newton(const TissueEnergy&, std::span<Vec3>, std::span<const char>,
                                        const MinimizeOptions&, const MinimizeProgress&,
                                        NewtonWorkspace*);
  /// The data for this tissue and free set, rebuilt (factor dropped) when they differ.
  Data& data_for(const LayeredTissue& tissue, std::span<const char> free);
  /// The factorisation (made on first use): kept when the data are rebuilt, since it analyses
  /// a new pattern by itself.
  DirectFactorization& factorization();
  std::unique_ptr<Data> data_;
  std::unique_ptr<DirectFactorization> factorization_;
  bool start_convex_ = false;  ///< for the next minimisation only
};

/// Minimises energy.energy() over the points marked free (options.gradient_tolerance, N;
/// options.max_iterations Newton steps). Every accepted step decreases the energy. With a
/// workspace, starts from its factor and leaves the last one in it.
MinimizeResult minimize_newton(const TissueEnergy& energy, std::span<Vec3> x,
                               std::span<const char> free, const MinimizeOptions& options,
                               const MinimizeProgress& progress = {},
                               NewtonWorkspace* workspace = nullptr);

}  // namespace incise::planning
