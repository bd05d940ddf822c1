// Integrators against the exact solution of a damped spring, and their energy behaviour.

#include <gtest/gtest.h>

#include <cmath>

#include "incise/core/error.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/physics/boundary_conditions.hpp"
#include "incise/physics/force_model.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"
#include "oscillator.hpp"

namespace incise {
namespace {

std::unique_ptr<Integrator> make(const std::string& name) {
  if (name == "explicit-euler") {
    return std::make_unique<ExplicitEuler>();
  }
  if (name == "symplectic-euler") {
    return std::make_unique<SymplecticEuler>();
  }
  if (name == "rk4") {
    return std::make_unique<RungeKutta4>();
  }
  if (name == "rk4-hierarchical") {
    // One vertex at the focus with one sub-step: the seed's per-vertex RK4 step.
    auto integrator = std::make_unique<HierarchicalRungeKutta4>(HierarchicalOptions{1, 0});
    integrator->set_focus(0);
    return integrator;
  }
  BackwardEulerOptions options;
  options.newton_steps = 1;
  return std::make_unique<BackwardEuler>(options);
}

/// |x(T) - exact| after integrating to T = 1 s with step dt.
double error_at_one_second(const std::string& scheme, double dt) {
  test::DampedOscillator oscillator(1.0, 100.0, 2.0);  // omega 10 rad/s, damping ratio 0.1
  std::vector<Vec3> x{Vec3(1.0, 0.0, 0.0)};
  std::vector<Vec3> v{Vec3::Zero()};
  auto integrator = make(scheme);
  const int steps = static_cast<int>(std::lround(1.0 / dt));
  for (int s = 0; s < steps; ++s) {
    integrator->step(oscillator, x, v, s * dt, dt);
  }
  return std::abs(x[0].x() - oscillator.exact(1.0, 1.0));
}

struct OrderCase {
  const char* scheme;
  double order;
};

class ConvergenceOrder : public ::testing::TestWithParam<OrderCase> {};

TEST_P(ConvergenceOrder, ErrorRatioWhenTheStepHalves) {
  const auto [scheme, order] = GetParam();
  const double coarse = error_at_one_second(scheme, 0.004);
  const double fine = error_at_one_second(scheme, 0.002);
  const double finer = error_at_one_second(scheme, 0.001);
  const double expected = std::pow(2.0, order);
  // Ratio near 2^order: 16 for RK4, 2 for the first-order schemes.
  EXPECT_NEAR(coarse / fine, expected, 0.1 * expected) << scheme;
  EXPECT_NEAR(fine / finer, expected, 0.1 * expected) << scheme;
  EXPECT_LT(finer, order > 2 ? 1e-9 : 5e-2);
}

INSTANTIATE_TEST_SUITE_P(Schemes, ConvergenceOrder,
                         ::testing::Values(OrderCase{"rk4", 4.0},
                                           OrderCase{"rk4-hierarchical", 4.0},
                                           OrderCase{"explicit-euler", 1.0},
                                           OrderCase{"symplectic-euler", 1.0},
                                           OrderCase{"backward-euler", 1.0}),
                         [](const ::testing::TestParamInfo<OrderCase>& param_info) {
                           std::string name = param_info.param.scheme;
                           for (char& c : name) {
                             c = c == '-' ? '_' : c;
                           }
                           return name;
                         });

struct EnergyTrace {
  double first_tenth_max_error = 0.0;  ///< max |E - E0| / E0 over the first tenth
  double last_tenth_max_error = 0.0;   ///< the same over the last tenth
  double final_relative = 0.0;         ///< (E_end - E0) / E0
};

EnergyTrace undamped_energy(const std::string& scheme, int steps, double dt) {
  test::DampedOscillator oscillator(1.0, 100.0, 0.0);
  std::vector<Vec3> x{Vec3(1.0, 0.0, 0.0)};
  std::vector<Vec3> v{Vec3::Zero()};
  auto integrator = make(scheme);
  const double e0 = oscillator.potential_energy(0.0, x);
  EnergyTrace trace;
  for (int s = 0; s < steps; ++s) {
    integrator->step(oscillator, x, v, s * dt, dt);
    const double energy =
        oscillator.potential_energy(0.0, x) + kinetic_energy(oscillator.masses(), v);
    const double error = std::abs(energy - e0) / e0;
    if (s < steps / 10) {
      trace.first_tenth_max_error = std::max(trace.first_tenth_max_error, error);
    }
    if (s >= steps - steps / 10) {
      trace.last_tenth_max_error = std::max(trace.last_tenth_max_error, error);
    }
    trace.final_relative = (energy - e0) / e0;
  }
  return trace;
}

TEST(EnergyBehaviour, SymplecticEulerStaysBounded) {
  // omega dt = 0.1 over about 1600 periods.
  const EnergyTrace trace = undamped_energy("symplectic-euler", 100000, 0.01);
  EXPECT_LT(trace.first_tenth_max_error, 0.06);  // oscillates with amplitude ~ omega dt / 2
  EXPECT_LT(trace.last_tenth_max_error, 0.06);   // and does not drift
  EXPECT_NEAR(trace.last_tenth_max_error, trace.first_tenth_max_error, 0.01);
}

TEST(EnergyBehaviour, ExplicitEulerGainsEnergy) {
  const EnergyTrace trace = undamped_energy("explicit-euler", 1000, 0.01);
  EXPECT_GT(trace.final_relative, 1.0);  // grows by (1 + (omega dt)^2) per step
}

TEST(EnergyBehaviour, Rk4LosesATinyAmountMonotonically) {
  const EnergyTrace trace = undamped_energy("rk4", 100000, 0.01);
  EXPECT_LT(trace.final_relative, 0.0);
  // Dissipation per step is about (omega dt)^6 / 144: 7e-9 here, 7e-4 over 1e5 steps.
  EXPECT_GT(trace.final_relative, -2e-3);
  EXPECT_LT(trace.first_tenth_max_error, trace.last_tenth_max_error);
}

TEST(EnergyBehaviour, BackwardEulerIsStableFarBeyondTheExplicitLimit) {
  test::DampedOscillator oscillator(1.0, 1e6, 0.0);  // omega 1000 rad/s
  std::vector<Vec3> x{Vec3(1.0, 0.0, 0.0)};
  std::vector<Vec3> v{Vec3::Zero()};
  BackwardEuler integrator;
  const double dt = 0.01;  // 5x beyond the explicit limit 2 / omega
  for (int s = 0; s < 100; ++s) {
    integrator.step(oscillator, x, v, s * dt, dt);
  }
  EXPECT_LT(std::abs(x[0].x()), 1e-3);  // decayed, never blew up
  EXPECT_GT(explicit_stability_limit(oscillator, "symplectic-euler"), 1.9e-3);
}

TEST(HierarchicalIterations, HalveWithDepthUpToTheBound) {
  HierarchicalRungeKutta4 integrator(HierarchicalOptions{8, 3});
  EXPECT_EQ(integrator.iterations_at_depth(0), 8);
  EXPECT_EQ(integrator.iterations_at_depth(1), 4);
  EXPECT_EQ(integrator.iterations_at_depth(2), 2);
  EXPECT_EQ(integrator.iterations_at_depth(3), 1);
  EXPECT_EQ(integrator.iterations_at_depth(4), 0);
  HierarchicalRungeKutta4 shallow(HierarchicalOptions{3, 4});
  EXPECT_EQ(shallow.iterations_at_depth(2), 1);  // never fewer than one inside the bound
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

/// The smallest model: only the core (masses, forces, energy). A linear spring on every edge
/// pulling towards rest length, with no per-vertex forces and no linearisation.
class CoreOnlySprings final : public ForceModel {
 public:
  explicit CoreOnlySprings(const TetMesh& mesh) : mesh_(mesh), masses_(mesh.vertex_count(), 0.01) {}
  [[nodiscard]] std::string name() const override { return "core-only springs"; }
  void refresh() override {}
  [[nodiscard]] double total_mass() const override { return 0.01 * mesh_.vertex_count(); }
  [[nodiscard]] std::span<const double> masses() const override { return masses_; }
  void add_forces(std::span<const Vec3> x, std::span<const Vec3> /*v*/,
                  std::span<Vec3> f) const override {
    for (std::size_t e = 0; e < mesh_.edge_count(); ++e) {
      const auto& [a, b] = mesh_.edge(static_cast<EdgeId>(e));
      const double rest = (mesh_.rest_position(a) - mesh_.rest_position(b)).norm();
      const Vec3 d = x[b] - x[a];
      const Vec3 force = kStiffness * (d.norm() - rest) * d.normalized();
      f[a] += force;
      f[b] -= force;
    }
  }
  [[nodiscard]] double elastic_energy(std::span<const Vec3> x) const override {
    double energy = 0.0;
    for (std::size_t e = 0; e < mesh_.edge_count(); ++e) {
      const auto& [a, b] = mesh_.edge(static_cast<EdgeId>(e));
      const double stretch =
          (x[b] - x[a]).norm() - (mesh_.rest_position(a) - mesh_.rest_position(b)).norm();
      energy += 0.5 * kStiffness * stretch * stretch;
    }
    return energy;
  }
  [[nodiscard]] double max_vertex_frequency() const override {
    return std::sqrt(40 * kStiffness / 0.01);
  }

 private:
  static constexpr double kStiffness = 10.0;  // N/m
  const TetMesh& mesh_;
  std::vector<double> masses_;
};

TEST(ForceModelCapabilities, ACoreOnlyModelRunsExplicitlyAndImplicitSchemesSayWhatIsMissing) {
  BoxGridOptions options;
  options.cells = {1, 1, 1};
  options.size = Vec3(0.1, 0.1, 0.1);
  TetMesh mesh = make_box_grid(options);
  CoreOnlySprings model(mesh);
  BoundaryConditions conditions(mesh);
  conditions.fix(vertices_in_box(mesh, Vec3(-1, -1, -1), Vec3(1, 1, 0)));
  conditions.set_gravity(Vec3(0, 0, -9.81));
  MechanicalSystem system(mesh, model, conditions);
  SimulationState state(mesh);
  RungeKutta4 rk4;
  const double dt = 0.5 * rk4.stability_limit(system);
  double lowest = 0.0;
  for (int step = 0; step < 200; ++step) {
    rk4.step(system, state.x.values(), state.v.values(), state.time, dt);
    state.time += dt;
    for (const Vec3& x : state.x.values()) {
      lowest = std::min(lowest, x.z());
    }
  }
  EXPECT_LT(lowest, -1e-4);  // the free top sags under gravity
  for (const Vec3& x : state.x.values()) {
    ASSERT_TRUE(x.allFinite());
  }
  BackwardEuler implicit;
  try {
    implicit.step(system, state.x.values(), state.v.values(), state.time, dt);
    FAIL() << "backward Euler ran without a linearisation";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("gives no linearisation"), std::string::npos)
        << error.what();
  }
}

}  // namespace
}  // namespace incise
