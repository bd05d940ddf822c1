#pragma once
// The functions of Teschner et al. that a prediction minimises, over the positions x (m) of
// every point of a LayeredTissue:
//   F_E  elastic energy (J): the sum of the spring law's energies, and with continuum
//        elasticity the corotated tetrahedra's energies;
//   F_V  volume preservation (J), sum over prisms of kappa |V0| ((V - V0) / V0)^2 / 2;
//   F_G  gravity's potential (J), -sum m_i g . (x_i - X_i) from the scanned positions X;
//   F_F  resulting forces, sum over free points of |f_i|^2 (N^2), f_i the spring (and
//        tetrahedra's) forces plus gravity on point i (the seed sums absolute values; squares
//        make it smooth).
// Energy minimisation minimises F_E + F_V + F_G; force minimisation F_F + k F_V (k, the mean
// spring stiffness, makes the units agree). Gradients are exact; the seed's F_F gradient is
// -2 H f with H the springs' Hessian, applied spring by spring.
//
// Thread rule: const methods are safe to call from several threads on distinct outputs.

#include <span>
#include <vector>

#include "incise/planning/layered_tissue.hpp"

namespace incise::planning {

/// The seed's energy of the layered tissue (springs or continuum, volume preservation,
/// gravity) and its gradient, evaluated in parallel. Reads the tissue, which must outlive it.
class TissueEnergy {
 public:
  /// `gravity` in m/s^2.
  TissueEnergy(const LayeredTissue& tissue, const Vec3& gravity);

  /// F_E + F_V + F_G, and its gradient (J/m) into `gradient` (every point) when not empty.
  double energy(std::span<const Vec3> x, std::span<Vec3> gradient = {}) const;
  /// The parts of energy() (J).
  [[nodiscard]] double spring_energy(std::span<const Vec3> x) const;
  /// The prisms' volume preservation (J).
  [[nodiscard]] double volume_energy(std::span<const Vec3> x) const;
  /// The continuum's tetrahedra (J); 0 with spring elasticity.
  [[nodiscard]] double elastic_energy(std::span<const Vec3> x) const;
  /// Spring (and tetrahedra's) forces plus gravity on every point (N), volume forces left out
  /// (the seed's f_i).
  void forces(std::span<const Vec3> x, std::span<Vec3> f) const;
  /// F_F + k F_V over the points marked free, and its gradient when not empty.
  double force_objective(std::span<const Vec3> x, std::span<const char> free,
                         std::span<Vec3> gradient = {}) const;
  /// Largest |force| (N) over free points, volume forces included (-grad of energy()).
  [[nodiscard]] double largest_free_force(std::span<const Vec3> x,
                                          std::span<const char> free) const;
  /// The tissue it evaluates.
  [[nodiscard]] const LayeredTissue& tissue() const { return tissue_; }
  /// The mean stiffness (N/m) of the springs and tetrahedra (each (2 mu + lambda) times its
  /// size), a scale for the force objective.
  [[nodiscard]] double mean_stiffness() const { return mean_stiffness_; }

 private:
  void add_volume(std::span<const Vec3> x, std::span<Vec3> gradient, double scale,
                  double& energy) const;
  void add_elastic(std::span<const Vec3> x, std::span<Vec3> gradient, double& energy) const;
  const LayeredTissue& tissue_;
  Vec3 gravity_;
  double mean_stiffness_ = 0.0;
};

}  // namespace incise::planning
