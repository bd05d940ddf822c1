// Mass-spring relaxation speed: the default scene (frames/s, physics only) and full RK4 steps
// on 0.1 m liver cubes of 6,000 and 48,000 tetrahedra. Results in BENCHMARKS.md.

#include <benchmark/benchmark.h>

#include <filesystem>

#include "incise/mesh/generators.hpp"
#include "incise/physics/mass_spring.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/scene/scene.hpp"
#include "incise/solve/integrators.hpp"

namespace {

using namespace incise;

/// One frame of scenes/block_press.json: the seed's 576-tet block pressed, hierarchical RK4.
void BM_DefaultSceneFrame(benchmark::State& state) {
  const SceneDescription scene =
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "block_press.json");
  TetMesh mesh = make_box_grid(scene.box);
  MassSpringModel model(mesh, scene.material, scene.mass_spring);
  BoundaryConditions conditions(mesh);
  for (const RegionSpec& region : scene.fixed) {
    conditions.fix(vertices_in_box(mesh, region.box->first, region.box->second));
  }
  for (const ForceSpec& force : scene.forces) {
    conditions.add_force(vertices_in_box(mesh, force.region.box->first, force.region.box->second),
                         force.force);
  }
  conditions.set_gravity(scene.gravity);
  MechanicalSystem system(mesh, model, conditions, scene.damping);
  SimulationState simulation(mesh);
  HierarchicalRungeKutta4 integrator(scene.integrator.hierarchical);
  const Vec3 focus = std::get<Vec3>(scene.integrator.focus);
  VertexId nearest = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if ((mesh.rest_position(static_cast<VertexId>(v)) - focus).norm() <
        (mesh.rest_position(nearest) - focus).norm()) {
      nearest = static_cast<VertexId>(v);
    }
  }
  integrator.set_focus(nearest);
  for (auto _ : state) {
    integrator.step(system, simulation.x.values(), simulation.v.values(), simulation.time,
                    scene.frame_dt);
    simulation.time += scene.frame_dt;
  }
  state.counters["frames/s"] =
      benchmark::Counter(1.0, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["tets"] = static_cast<double>(mesh.tet_count());
  state.counters["sweeps"] = integrator.last_sweeps();
}
BENCHMARK(BM_DefaultSceneFrame)->Unit(benchmark::kMicrosecond);

/// One global RK4 step on an n^3-cell liver cube (6 tets per cell) hanging from its top.
void BM_Rk4Step(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  BoxGridOptions options;
  options.cells = {n, n, n};
  options.size = Vec3(0.1, 0.1, 0.1);
  TetMesh mesh = make_box_grid(options);
  MassSpringModel model(mesh, material_preset("liver"), {});
  BoundaryConditions conditions(mesh);
  conditions.fix(vertices_in_box(mesh, Vec3(-1, -1, 0.1 - 1e-9), Vec3(1, 1, 1)));
  conditions.set_gravity(Vec3(0, 0, -9.81));
  MechanicalSystem system(mesh, model, conditions, {0.0, 10.0});
  SimulationState simulation(mesh);
  RungeKutta4 integrator;
  const double dt = 0.9 * explicit_stability_limit(system, "rk4");
  for (auto _ : state) {
    integrator.step(system, simulation.x.values(), simulation.v.values(), simulation.time, dt);
    simulation.time += dt;
  }
  state.counters["steps/s"] =
      benchmark::Counter(1.0, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["tets"] = static_cast<double>(mesh.tet_count());
  state.counters["dt_us"] = dt * 1e6;
}
BENCHMARK(BM_Rk4Step)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
