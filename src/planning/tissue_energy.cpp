#include "incise/planning/tissue_energy.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "incise/planning/minimize.hpp"
#include "incise/planning/prism.hpp"
#include "tissue_pattern.hpp"

namespace incise::planning {

TissueEnergy::TissueEnergy(const LayeredTissue& tissue, const Vec3& gravity)
    : tissue_(tissue), gravity_(gravity) {
  double sum = 0.0;
  for (const Spring& s : tissue.springs) {
    sum += s.stiffness;
  }
  std::size_t count = tissue.springs.size();
  // A tetrahedron's stiffness scale (N/m): (2 mu + lambda) times its size.
  for (const Prism& prism : tissue.prisms) {
    for (const PrismTet& tet : prism.tets) {
      if (tet.rest.volume > 0.0) {
        sum += (2.0 * prism.material.mu + prism.material.lambda) * std::cbrt(tet.rest.volume);
        ++count;
      }
    }
  }
  mean_stiffness_ = count == 0 ? 0.0 : sum / static_cast<double>(count);
}

double TissueEnergy::spring_energy(std::span<const Vec3> x) const {
  double energy = 0.0;
  for (const Spring& s : tissue_.springs) {
    const double length =
        (x[static_cast<std::size_t>(s.a)] - x[static_cast<std::size_t>(s.b)]).norm();
    energy += tissue_.law.energy(length, s.rest_length, s.stiffness);
  }
  return energy;
}

double TissueEnergy::elastic_energy(std::span<const Vec3> x) const {
  double energy = 0.0;
  add_elastic(x, {}, energy);
  return energy;
}

void TissueEnergy::add_elastic(std::span<const Vec3> x, std::span<Vec3> gradient,
                               double& energy) const {
  if (tissue_.elasticity != TissueElasticity::kContinuum) {
    return;
  }
  // Each tetrahedron's energy and forces on worker threads (the invariants and their
  // derivatives are the work), summed in prism order.
  const bool with_gradient = !gradient.empty();
  const std::size_t prisms = tissue_.prisms.size();
  std::vector<double> tet_energy(3 * std::min(kPrismBlock, prisms));
  std::vector<ElementForces> tet_forces(with_gradient ? tet_energy.size() : 0);
  for_prism_blocks(
      prisms, 64,
      [&](std::size_t p, std::size_t k) {
        const Prism& prism = tissue_.prisms[p];
        for (std::size_t t = 0; t < 3; ++t) {
          const PrismTet& tet = prism.tets[t];
          if (tet.rest.volume != 0.0) {
            const Corners corners = tet_corners(prism, tet, x);
            tet_energy[3 * k + t] =
                with_gradient ? neo_hookean_energy_and_forces(corners, tet.rest, prism.material,
                                                              tet_forces[3 * k + t])
                              : neo_hookean_energy(corners, tet.rest, prism.material);
          }
        }
      },
      [&](std::size_t first, std::size_t last) {  // summed in prism order
        for (std::size_t p = first; p < last; ++p) {
          const Prism& prism = tissue_.prisms[p];
          const std::size_t k = p - first;
          for (std::size_t t = 0; t < 3; ++t) {
            const PrismTet& tet = prism.tets[t];
            if (tet.rest.volume == 0.0) {
              continue;
            }
            energy += tet_energy[3 * k + t];
            for (std::size_t i = 0; i < 4 && with_gradient; ++i) {
              gradient[static_cast<std::size_t>(prism.points[tet.corners[i]])] -=
                  tet_forces[3 * k + t][i];
            }
          }
        }
      });
}

double TissueEnergy::volume_energy(std::span<const Vec3> x) const {
  double energy = 0.0;
  add_volume(x, {}, 1.0, energy);
  return energy;
}

void TissueEnergy::add_volume(std::span<const Vec3> x, std::span<Vec3> gradient, double scale,
                              double& energy) const {
  if (!(tissue_.volume_weight > 0.0)) {
    return;
  }
  const double kappa = tissue_.volume_weight * scale;
  const bool with_gradient = !gradient.empty();
  const std::size_t prisms = tissue_.prisms.size();
  std::vector<double> prism_energy(std::min(kPrismBlock, prisms));
  std::vector<std::array<Vec3, 6>> prism_gradient(with_gradient ? prism_energy.size() : 0);
  for_prism_blocks(
      prisms, 256,
      [&](std::size_t p, std::size_t k) {
        const Prism& prism = tissue_.prisms[p];
        if (prism.rest_volume == 0.0) {
          return;
        }
        PrismPoints corners;
        for (std::size_t i = 0; i < 6; ++i) {
          corners[i] = x[static_cast<std::size_t>(prism.points[i])];
        }
        const double change = prism_volume(corners) - prism.rest_volume;
        const double magnitude = std::abs(prism.rest_volume);
        prism_energy[k] = 0.5 * kappa * change * change / magnitude;
        if (with_gradient) {
          const std::array<Vec3, 6> dv = prism_volume_gradient(corners);
          const double factor = kappa * change / magnitude;
          for (std::size_t i = 0; i < 6; ++i) {
            prism_gradient[k][i] = factor * dv[i];
          }
        }
      },
      [&](std::size_t first, std::size_t last) {  // summed in prism order
        for (std::size_t p = first; p < last; ++p) {
          const Prism& prism = tissue_.prisms[p];
          if (prism.rest_volume == 0.0) {
            continue;
          }
          energy += prism_energy[p - first];
          for (std::size_t i = 0; i < 6 && with_gradient; ++i) {
            gradient[static_cast<std::size_t>(prism.points[i])] += prism_gradient[p - first][i];
          }
        }
      });
}

double TissueEnergy::energy(std::span<const Vec3> x, std::span<Vec3> gradient) const {
  double energy = 0.0;
  const bool with_gradient = !gradient.empty();
  if (with_gradient) {
    std::fill(gradient.begin(), gradient.end(), Vec3::Zero());
  }
  for (const Spring& s : tissue_.springs) {
    const Vec3 d = x[static_cast<std::size_t>(s.a)] - x[static_cast<std::size_t>(s.b)];
    const double length = d.norm();
    energy += tissue_.law.energy(length, s.rest_length, s.stiffness);
    if (with_gradient && length > 0.0) {
      const Vec3 g = (tissue_.law.tension(length, s.rest_length, s.stiffness) / length) * d;
      gradient[static_cast<std::size_t>(s.a)] += g;
      gradient[static_cast<std::size_t>(s.b)] -= g;
    }
  }
  // Gravity's potential relative to the rest state: the same gradient, and no large constant
  // whose rounding would hide the small decreases a converging line search needs.
  for (std::size_t i = 0; i < x.size(); ++i) {
    energy -= tissue_.mass[i] * gravity_.dot(x[i] - tissue_.rest[i]);
    if (with_gradient) {
      gradient[i] -= tissue_.mass[i] * gravity_;
    }
  }
  add_volume(x, gradient, 1.0, energy);
  add_elastic(x, gradient, energy);
  return energy;
}

void TissueEnergy::forces(std::span<const Vec3> x, std::span<Vec3> f) const {
  for (std::size_t i = 0; i < x.size(); ++i) {
    f[i] = tissue_.mass[i] * gravity_;
  }
  for (const Spring& s : tissue_.springs) {
    const Vec3 d = x[static_cast<std::size_t>(s.a)] - x[static_cast<std::size_t>(s.b)];
    const double length = d.norm();
    if (length > 0.0) {
      const Vec3 g = (tissue_.law.tension(length, s.rest_length, s.stiffness) / length) * d;
      f[static_cast<std::size_t>(s.a)] -= g;
      f[static_cast<std::size_t>(s.b)] += g;
    }
  }
  if (tissue_.elasticity == TissueElasticity::kContinuum) {
    // The tetrahedra's forces are -grad of their energy.
    std::vector<Vec3> gradient(x.size(), Vec3::Zero());
    double unused = 0.0;
    add_elastic(x, gradient, unused);
    for (std::size_t i = 0; i < x.size(); ++i) {
      f[i] -= gradient[i];
    }
  }
}

double TissueEnergy::force_objective(std::span<const Vec3> x, std::span<const char> free,
                                     std::span<Vec3> gradient) const {
  std::vector<Vec3> f(x.size());
  forces(x, f);
  double objective = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (free[i] == 0) {
      f[i].setZero();
    }
    objective += f[i].squaredNorm();
  }
  if (!gradient.empty()) {
    // d|f|^2/dx = 2 (df/dx)^T f = -2 H f, H symmetric: per spring the block
    // K = E'' u u^T + (E' / l) (I - u u^T) acting on f_a - f_b.
    std::fill(gradient.begin(), gradient.end(), Vec3::Zero());
    for (const Spring& s : tissue_.springs) {
      const auto a = static_cast<std::size_t>(s.a);
      const auto b = static_cast<std::size_t>(s.b);
      const Vec3 d = x[a] - x[b];
      const double length = d.norm();
      if (!(length > 0.0)) {
        continue;
      }
      const Vec3 u = d / length;
      const Vec3 w = f[a] - f[b];
      const double along = u.dot(w);
      const double tension = tissue_.law.tension(length, s.rest_length, s.stiffness);
      const double slope = tissue_.law.tension_derivative(length, s.rest_length, s.stiffness);
      const Vec3 kw = slope * along * u + (tension / length) * (w - along * u);
      gradient[a] -= 2.0 * kw;
      gradient[b] += 2.0 * kw;
    }
    if (tissue_.elasticity == TissueElasticity::kContinuum) {
      for (const Prism& prism : tissue_.prisms) {
        for (const PrismTet& tet : prism.tets) {
          if (tet.rest.volume == 0.0) {
            continue;
          }
          ElementForces w;
          for (std::size_t i = 0; i < 4; ++i) {
            w[i] = f[static_cast<std::size_t>(prism.points[tet.corners[i]])];
          }
          const ElementForces kw = neo_hookean_stiffness_product(tet_corners(prism, tet, x),
                                                                 tet.rest, prism.material, w);
          for (std::size_t i = 0; i < 4; ++i) {
            gradient[static_cast<std::size_t>(prism.points[tet.corners[i]])] -= 2.0 * kw[i];
          }
        }
      }
    }
  }
  add_volume(x, gradient, mean_stiffness_, objective);
  return objective;
}

double TissueEnergy::largest_free_force(std::span<const Vec3> x, std::span<const char> free) const {
  std::vector<Vec3> gradient(x.size());
  (void)energy(x, gradient);
  return largest_free(gradient, free);
}

}  // namespace incise::planning
