// Static solves of the FEM cantilever (0.1 x 0.01 x 0.01 m, E = 1e7 Pa, nu = 0.3, clamped at
// x = 0, under gravity) at growing size, by each linear solver Newton's method can use:
// block-Jacobi CG, the direct factorisation (CHOLMOD supernodal where built with it) and auto
// (the default for static scenes). Prints one row per run; results in BENCHMARKS.md.
//
//   static_solve_bench [--max-tets N]

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "incise/mesh/generators.hpp"
#include "incise/physics/boundary_conditions.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"

namespace {

using namespace incise;
using Clock = std::chrono::steady_clock;

struct Size {
  int nx, ny, nz;
};

struct Solver {
  const char* name;
  LinearSolverType type;
};

void run(const Size& size, const Solver& solver) {
  BoxGridOptions box;
  box.cells = {size.nx, size.ny, size.nz};
  box.size = Vec3(0.1, 0.01, 0.01);
  box.tets_per_cell = 6;
  TetMesh mesh = make_box_grid(box);
  Material material;
  material.young_modulus = 1e7;  // Pa
  material.poisson_ratio = 0.3;
  material.density = 1000.0;  // kg/m^3
  CorotationalFemParameters parameters;
  parameters.tangent = TangentKind::kProjected;
  CorotationalFemModel model(mesh, material, parameters);
  BoundaryConditions conditions(mesh);
  conditions.fix(vertices_in_box(mesh, Vec3(-1, -1, -1), Vec3(1e-4, 1, 1)));
  conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  MechanicalSystem system(mesh, model, conditions);
  SimulationState state(mesh);
  StaticOptions options;
  options.solver.type = solver.type;
  StaticEquilibrium integrator(options);
  const auto start = Clock::now();
  const bool converged = integrator.solve(system, state.x.values(), 1.0);
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  double tip = 0.0;  // m, largest downward deflection
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    tip = std::max(tip, mesh.rest_position(static_cast<VertexId>(i)).z() - state.x.values()[i].z());
  }
  std::printf("| %d x %d x %d | %zu | %s | %d | %lld | %.2f | %.2f | %.4f | %.1e | %s |\n", size.nx,
              size.ny, size.nz, mesh.tet_count(), solver.name, integrator.last_iterations(),
              integrator.last_linear_iterations(), integrator.last_factorization_seconds(), seconds,
              tip * 1e3, integrator.last_residual(), converged ? "yes" : "no");
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t max_tets = 40000;
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "--max-tets") == 0) {
      max_tets = std::strtoull(argv[i + 1], nullptr, 10);
    }
  }
  const std::vector<Size> sizes = {{80, 2, 2}, {40, 4, 4}, {80, 4, 4}, {80, 8, 8}, {160, 8, 8}};
  const std::vector<Solver> solvers = {{"cg (block-Jacobi)", LinearSolverType::kConjugateGradient},
                                       {"direct", LinearSolverType::kDirect},
                                       {"auto", LinearSolverType::kAuto}};
  std::printf("direct backend: %s\n",
              has_cholmod_backend() ? "CHOLMOD supernodal" : "Eigen SimplicialLDLT");
  std::printf(
      "| cells | tets | solver | Newton | CG iterations | factor s | total s | tip mm | residual | "
      "converged |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Size& size : sizes) {
    if (static_cast<std::size_t>(size.nx * size.ny * size.nz * 6) > max_tets) {
      continue;
    }
    for (const Solver& solver : solvers) {
      run(size, solver);
    }
  }
  return 0;
}
