#include "incise/planning/equilibrium.hpp"

#include <fmt/format.h>

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/planning/tissue_energy.hpp"
#include "incise/solve/anderson_mixing.hpp"
#include "incise/solve/direct_factorization.hpp"
#include "point_block_matrix.hpp"
#include "tissue_pattern.hpp"

namespace incise::planning {

namespace {

/// The shortest rest length the initialisation may give a spring, relative to its length.
constexpr double kShortest = 0.05;
constexpr const char* kSetNames[] = {"layer", "connecting", "diagonal"};
/// Relative Levenberg-Marquardt damping of the first Gauss-Newton step, and the least.
constexpr double kDamping = 1e-3;
constexpr double kLeastDamping = 1e-9;

double largest_soft_force(const LayeredTissue& tissue, std::span<const Vec3> f) {
  double largest = 0.0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (tissue.kind[i] == PointKind::kSoft) {
      largest = std::max(largest, f[i].norm());
    }
  }
  return largest;
}

/// The first of each soft point's three rows in `row` (-1 for the others); returns the rows.
int soft_rows(const LayeredTissue& tissue, std::vector<int>& row) {
  row.assign(tissue.point_count(), -1);
  int rows = 0;
  for (std::size_t i = 0; i < row.size(); ++i) {
    if (tissue.kind[i] == PointKind::kSoft) {
      row[i] = rows;
      rows += 3;
    }
  }
  return rows;
}

double mean_skin_prestrain(const LayeredTissue& tissue) {
  double strain_sum = 0.0;
  int skin_springs = 0;
  for (const Spring& spring : tissue.springs) {
    if (spring.set == SpringSet::kLayer && spring.layer == 0) {
      const double scanned = (tissue.rest[static_cast<std::size_t>(spring.a)] -
                              tissue.rest[static_cast<std::size_t>(spring.b)])
                                 .norm();
      strain_sum += scanned / spring.rest_length - 1.0;
      ++skin_springs;
    }
  }
  return skin_springs > 0 ? strain_sum / skin_springs : 0.0;
}

/// The chord steps Anderson mixes over: 60 -> 15 steps on a 59k-point CT model (depth 3: 16),
/// 55 -> 17 on headsq's.
constexpr int kAndersonDepth = 5;

/// Continuum elasticity: the rest shape of the tetrahedra is moved (the soft points' rest
/// positions X) so that the scanned state x is in equilibrium; the skin membrane keeps its
/// pre-strain exactly. With f(x; X) = -K (x - X) to first order, the chord iteration
/// X <- X - K^-1 r (K the stiffness at the scanned state, factorised once and again only when
/// the residual stops falling) converges linearly at the rate of the strains the load makes,
/// which are small for tissue that carries its own weight. (Refactorising whenever the
/// residual did not halve bought nothing: K hardly changes with X, and each factorisation
/// cost 20 cheap steps. On the phantom head of bench/head_phantom.py: 8.3 s -> 1.6 s.) The
/// steps are mixed by Anderson's acceleration, restarted whenever the stiffness is factorised
/// again (after a step that did not lower the residual by a tenth, or left a sliver); each solve is
/// in single precision (the residual is the forces', in double: the answer is the same). `f` holds
/// the forces at the scanned state, `report` the residual before; `lent`, if given, the
/// factorisation to use (its analysis kept for the caller's next solve of this pattern).
EquilibriumReport balance_continuum(LayeredTissue& tissue, const TissueEnergy& energy,
                                    std::vector<Vec3>& f, EquilibriumReport report,
                                    double tolerance, int max_iterations,
                                    DirectFactorization* lent) {
  const std::size_t n = tissue.point_count();
  const std::span<const Vec3> x = tissue.rest;
  report.residual_after = report.residual_before;
  report.skin_prestrain_mean = mean_skin_prestrain(tissue);
  std::vector<int> row;
  const int rows = soft_rows(tissue, row);
  const CouplingPattern pattern = coupling_pattern(tissue);
  PointBlockMatrix stiffness(row, rows, pattern.pairs);
  const std::vector<PointBlockMatrix::Target> targets = prism_targets(tissue, pattern, stiffness);
  DirectFactorization own;
  DirectFactorization& factorization = lent != nullptr ? *lent : own;
  std::vector<Vec3> rest(x.begin(), x.end());
  bool factorised = false;
  double previous_residual = report.residual_before;
  AndersonMixing anderson(kAndersonDepth);
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    if (report.residual_after <= tolerance || rows == 0) {
      break;
    }
    if (!factorised || report.residual_after > 0.9 * previous_residual) {
      stiffness.clear();
      // The exact tangent (positive definite near the scanned state), else its convex form
      // (once each: the tangent is factorised only once when it is positive definite).
      add_prism_hessians(tissue, targets, x, {.tets = true}, stiffness);
      bool factorised_now = factorization.factorize_preconditioner(stiffness.matrix(), true);
      if (!factorised_now) {
        stiffness.clear();
        add_prism_hessians(tissue, targets, x, {.tets = true, .convex = true}, stiffness);
        factorised_now = factorization.factorize_preconditioner(stiffness.matrix(), false);
      }
      if (!factorised_now) {
        throw InputError(
            "equilibrium initialisation: the tissue's stiffness could not be factorised (a soft "
            "point in no tetrahedron?)");
      }
      factorised = true;
      // A new matrix, a new iteration: the old steps do not mix with it. (This is also where a
      // mixed step that raised the residual, or left a sliver, restarts the mixing.)
      anderson.restart();
    }
    previous_residual = report.residual_after;
    Eigen::VectorXd rhs(rows);
    for (std::size_t i = 0; i < n; ++i) {
      if (row[i] >= 0) {
        rhs.segment<3>(row[i]) = f[i];
      }
    }
    const Eigen::VectorXd shift = factorization.solve_single_precision(rhs);
    Eigen::VectorXd at(rows);
    for (std::size_t i = 0; i < n; ++i) {
      if (row[i] >= 0) {
        at.segment<3>(row[i]) = rest[i];
      }
    }
    const Eigen::VectorXd next = anderson.next(at, -shift);
    for (std::size_t i = 0; i < n; ++i) {
      if (row[i] >= 0) {
        rest[i] = next.segment<3>(row[i]);
      }
    }
    if (set_tet_rest_shapes(tissue, rest) > 0) {
      factorised = false;  // a sliver left: the stiffness changed
    }
    energy.forces(x, f);
    report.residual_after = largest_soft_force(tissue, f);
    report.iterations = iteration + 1;
  }
  for (std::size_t i = 0; i < n; ++i) {
    report.largest_rest_shift = std::max(report.largest_rest_shift, (rest[i] - x[i]).norm());
    if (tissue.kind[i] != PointKind::kSoft) {
      report.load_on_fixed_points += f[i];
    }
  }
  return report;
}

}  // namespace

EquilibriumReport initialise_equilibrium(LayeredTissue& tissue, const Vec3& gravity,
                                         double tolerance, int max_iterations,
                                         DirectFactorization* lent) {
  EquilibriumReport report;
  const std::size_t n = tissue.point_count();
  const std::span<const Vec3> x = tissue.rest;
  std::vector<Vec3> f(n);
  const TissueEnergy energy(tissue, gravity);
  energy.forces(x, f);
  report.residual_before = largest_soft_force(tissue, f);
  if (tissue.elasticity == TissueElasticity::kContinuum) {
    return balance_continuum(tissue, energy, f, report, tolerance, max_iterations, lent);
  }
  // Damped steps converge linearly: a few more of them than Gauss-Newton would need.
  // Soft points are the rows; every spring is an unknown. The skin's too: on an irregular
  // triangulation a uniform pre-strain leaves in-plane forces that only in-plane springs can
  // balance (through the nearly radial springs below it would take huge changes); their mean
  // pre-strain stays close to the given one (reported).
  std::vector<int> row;
  const int rows = soft_rows(tissue, row);
  std::vector<double> scanned(tissue.springs.size());
  for (std::size_t s = 0; s < tissue.springs.size(); ++s) {
    scanned[s] = (x[static_cast<std::size_t>(tissue.springs[s].a)] -
                  x[static_cast<std::size_t>(tissue.springs[s].b)])
                     .norm();
  }
  const std::vector<double> original = [&] {
    std::vector<double> lengths;
    for (const Spring& s : tissue.springs) {
      lengths.push_back(s.rest_length);
    }
    return lengths;
  }();
  // B L^2 B^T has a fixed pattern: built once, refilled in place each iteration.
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(tissue.springs.size());
  for (const Spring& spring : tissue.springs) {
    pairs.emplace_back(spring.a, spring.b);
  }
  PointBlockMatrix system(row, rows, pairs);
  DirectFactorization own;  // CHOLMOD where built with it; the pattern is kept
  DirectFactorization& factorization = lent != nullptr ? *lent : own;
  // Levenberg-Marquardt damping, relative to each row's diagonal: a point whose springs are
  // nearly coplanar (an oblique column in a concave fold) cannot be balanced across their plane
  // without huge changes; damping leaves it a residual at first. It shrinks tenfold per step
  // that reduces the residual (and grows back otherwise), so the steps end as Gauss-Newton's.
  double damping = kDamping;
  double previous_residual = report.residual_before;
  // f holds the forces at the current rest lengths throughout.
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    report.residual_after = largest_soft_force(tissue, f);
    if (report.residual_after <= tolerance || rows == 0) {
      break;
    }
    if (iteration > 0) {
      damping = report.residual_after < previous_residual ? std::max(damping * 0.1, kLeastDamping)
                                                          : std::min(damping * 10.0, 1.0);
    }
    previous_residual = report.residual_after;
    // df/dl0 of spring s: -t u at a, +t u at b (t = d tension / d rest length, u from b to a).
    // Minimal relative change: dl0 = L^2 B^T y with (B L^2 B^T) y = -f.
    std::vector<double> t(tissue.springs.size(), 0.0);
    std::vector<Vec3> u(tissue.springs.size(), Vec3::Zero());
    system.clear();
    double largest_diagonal = 0.0;
    for (std::size_t s = 0; s < tissue.springs.size(); ++s) {
      const Spring& spring = tissue.springs[s];
      if (!(scanned[s] > 0.0)) {
        continue;
      }
      const auto a = static_cast<std::size_t>(spring.a);
      const auto b = static_cast<std::size_t>(spring.b);
      u[s] = (x[a] - x[b]) / scanned[s];
      t[s] = tissue.law.tension_by_rest(scanned[s], spring.rest_length, spring.stiffness);
      const double w = t[s] * t[s] * spring.rest_length * spring.rest_length;
      const Mat3 block = w * u[s] * u[s].transpose();
      largest_diagonal = std::max(largest_diagonal, w);
      system.add_diagonal(spring.a, block);
      system.add_diagonal(spring.b, block);
      system.add_coupling(s, -block);
    }
    system.damp_diagonal(damping, 1e-12 * largest_diagonal);
    Eigen::VectorXd rhs(rows);
    for (std::size_t i = 0; i < n; ++i) {
      if (row[i] >= 0) {
        rhs.segment<3>(row[i]) = -f[i];
      }
    }
    if (!factorization.factorize(system.matrix())) {
      throw InputError("equilibrium initialisation: the spring system could not be factorised");
    }
    const Eigen::VectorXd y = factorization.solve(rhs);
    for (std::size_t s = 0; s < tissue.springs.size(); ++s) {
      Spring& spring = tissue.springs[s];
      if (t[s] == 0.0) {
        continue;
      }
      double bt = 0.0;
      const int ra = row[static_cast<std::size_t>(spring.a)];
      const int rb = row[static_cast<std::size_t>(spring.b)];
      if (ra >= 0) {
        bt -= t[s] * u[s].dot(Vec3(y.segment<3>(ra)));
      }
      if (rb >= 0) {
        bt += t[s] * u[s].dot(Vec3(y.segment<3>(rb)));
      }
      // A step changes a rest length by at most half of it; the next step goes on from there.
      const double change = std::clamp(spring.rest_length * spring.rest_length * bt,
                                       -0.5 * spring.rest_length, 0.5 * spring.rest_length);
      if (std::abs(change) == 0.5 * spring.rest_length) {
        ++report.limited_changes;
      }
      spring.rest_length += change;
      if (!(spring.rest_length > kShortest * scanned[s])) {
        throw InputError(
            fmt::format("equilibrium initialisation: the tissue cannot carry its load: the {} "
                        "spring of layer {} between points {} and {} ({:.3g} mm long) would "
                        "need a rest length below {} of its length; stiffen the layers, lower "
                        "the skin pre-strain or the gravity",
                        kSetNames[static_cast<int>(spring.set)], spring.layer, spring.a, spring.b,
                        scanned[s] * 1e3, kShortest));
      }
    }
    report.iterations = iteration + 1;
    energy.forces(x, f);
  }
  report.residual_after = largest_soft_force(tissue, f);
  for (std::size_t s = 0; s < tissue.springs.size(); ++s) {
    report.largest_relative_change =
        std::max(report.largest_relative_change,
                 std::abs(tissue.springs[s].rest_length - original[s]) / original[s]);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (tissue.kind[i] != PointKind::kSoft) {
      report.load_on_fixed_points += f[i];
    }
  }
  report.skin_prestrain_mean = mean_skin_prestrain(tissue);
  return report;
}

}  // namespace incise::planning
