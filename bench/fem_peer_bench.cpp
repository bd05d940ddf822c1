// The corotational FEM peer comparison (issue: "Corotational FEM with implicit integration").
// Workload: a 0.1 m cube of n^3 cells, 6 tets per cell, E = 3 kPa, nu = 0.45, 1000 kg/m^3, the
// z = 0 face fixed, gravity -9.81 m/s^2 along z, dt = 0.01 s, 100 steps from rest, one Newton
// step. incise and Bullet's deformable solver (btDeformableMultiBodyDynamicsWorld with
// btDeformableLinearElasticityForce, double precision) run alternately on the identical mesh
// and masses; the table gives ms/step, the ratio and both final sags. Also: where incise's
// time goes, incise variants (matrix-free products, preconditioners), and a STREAM-style triad
// so the CG iteration cost can be set against memory bandwidth.
//
//   fem_peer_bench [--cells 10,20] [--steps 100] [--repeats 2] [--no-variants] [--no-peer]

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "incise/core/timing.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"

#ifdef INCISE_WITH_BULLET
#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <btBulletDynamicsCommon.h>
#endif

namespace {

using namespace incise;

constexpr double kYoung = 3.0e3;     // Pa
constexpr double kPoisson = 0.45;    // -
constexpr double kDensity = 1000.0;  // kg/m^3
constexpr double kSize = 0.1;        // m
constexpr double kDt = 0.01;         // s

BoxGridOptions cube(int cells) {
  BoxGridOptions options;
  options.cells = {cells, cells, cells};
  options.size = Vec3(kSize, kSize, kSize);
  return options;
}

Material tissue() {
  Material m;
  m.young_modulus = kYoung;
  m.poisson_ratio = kPoisson;
  m.density = kDensity;
  return m;
}

VertexId top_centre(const TetMesh& mesh) {
  VertexId best = 0;
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    const auto v = static_cast<VertexId>(i);
    if ((mesh.rest_position(v) - Vec3(0.05, 0.05, 0.1)).norm() <
        (mesh.rest_position(best) - Vec3(0.05, 0.05, 0.1)).norm()) {
      best = v;
    }
  }
  return best;
}

std::vector<VertexId> bottom(const TetMesh& mesh) {
  std::vector<VertexId> vertices;
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    if (mesh.rest_position(static_cast<VertexId>(i)).z() < 1e-9) {
      vertices.push_back(static_cast<VertexId>(i));
    }
  }
  return vertices;
}

struct IncisePlan {
  std::string name;
  incise::Preconditioner preconditioner = incise::Preconditioner::kBlockJacobi;
  bool assemble = true;
  int start_history = incise::LinearSolverOptions{}.start_history;
  bool single_precision_products = incise::LinearSolverOptions{}.single_precision_products;
};

struct InciseRun {
  double ms_per_step = 0.0;
  double sag = 0.0;  ///< m, top centre
  double iterations_per_step = 0.0;
  double forces = 0.0, assembly = 0.0, preconditioner = 0.0, products = 0.0, vector_updates = 0.0,
         start = 0.0,
         total = 0.0;  ///< s over all steps
  std::size_t blocks = 0;
};

InciseRun run_incise(int cells, int steps, const IncisePlan& plan) {
  TetMesh mesh = make_box_grid(cube(cells));
  CorotationalFemParameters parameters;
  parameters.assemble = plan.assemble;
  CorotationalFemModel model(mesh, tissue(), parameters);
  BoundaryConditions conditions(mesh);
  conditions.fix(bottom(mesh));
  conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  MechanicalSystem system(mesh, model, conditions);
  SimulationState state(mesh);
  BackwardEulerOptions options;
  options.newton_steps = 1;
  options.solver.tolerance = 1e-6;
  options.solver.max_iterations = 1000;
  options.solver.preconditioner = plan.preconditioner;
  options.solver.assembled = plan.assemble;
  options.solver.start_history = plan.start_history;
  options.solver.single_precision_products = plan.single_precision_products;
  BackwardEuler integrator(options);
  InciseRun run;
  const auto start = Clock::now();
  for (int s = 0; s < steps; ++s) {
    integrator.step(system, state.x.values(), state.v.values(), s * kDt, kDt);
    const IntegratorStats& stats = integrator.stats();
    run.iterations_per_step += static_cast<double>(stats.solver_iterations_last_step);
    run.forces += stats.seconds_forces;
    run.assembly += model.last_assembly_seconds();
    run.preconditioner += stats.seconds_preconditioner;
    run.products += stats.seconds_products;
    run.vector_updates += stats.seconds_vector_updates;
    run.start += stats.seconds_solver_start;
  }
  run.total = seconds_since(start);
  run.ms_per_step = 1e3 * run.total / steps;
  run.iterations_per_step /= steps;
  const VertexId centre = top_centre(mesh);
  run.sag = mesh.rest_position(centre).z() - state.x[centre].z();
  BlockSparseMatrix matrix;
  (void)model.assemble_linearization(1.0, 0.0, matrix);
  run.blocks = matrix.block_count();
  return run;
}

#ifdef INCISE_WITH_BULLET
/// Exposes the solver's Newton and CG settings, which Bullet keeps protected.
class PeerSolver : public btDeformableBodySolver {
 public:
  void configure(int newton_steps, double relative_tolerance, int max_iterations) {
    m_maxNewtonIterations = newton_steps;
    // Bullet skips the solve when |residual| < this absolute tolerance (1e-4 by default), which
    // a 10 cm body of 1 kg never exceeds: the body would not move at all.
    m_newtonTolerance = 1e-30;
    // Bullet stops when r.z <= tol * min(1, z0.b): a squared, preconditioned relative residual.
    m_cg.m_tolerance = relative_tolerance * relative_tolerance;
    m_cg.m_maxIterations = max_iterations;
    m_cr.m_tolerance = relative_tolerance * relative_tolerance;
    m_cr.m_maxIterations = max_iterations;
  }
};

struct BulletRun {
  double ms_per_step = 0.0;
  double sag = 0.0;
};

BulletRun run_bullet(int cells, int steps) {
  TetMesh mesh = make_box_grid(cube(cells));
  // The same lumped masses as incise's.
  CorotationalFemModel model(mesh, tissue());
  std::string node = std::to_string(mesh.vertex_count()) + " 3 0 0\n";
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    const Vec3& p = mesh.rest_position(static_cast<VertexId>(i));
    char line[128];
    std::snprintf(line, sizeof line, "%zu %.17g %.17g %.17g\n", i, p.x(), p.y(), p.z());
    node += line;
  }
  std::string ele = std::to_string(mesh.tet_count()) + " 4 0\n";
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    ele += std::to_string(t) + " " + std::to_string(tet[0]) + " " + std::to_string(tet[1]) + " " +
           std::to_string(tet[2]) + " " + std::to_string(tet[3]) + "\n";
  }
  btSoftBodyRigidBodyCollisionConfiguration configuration;
  btCollisionDispatcher dispatcher(&configuration);
  btDbvtBroadphase broadphase;
  PeerSolver deformable_solver;
  deformable_solver.setImplicit(true);
  const char* tolerance = std::getenv("INCISE_BENCH_BULLET_TOLERANCE");
  const char* iterations = std::getenv("INCISE_BENCH_BULLET_ITERATIONS");
  deformable_solver.configure(1, tolerance != nullptr ? std::atof(tolerance) : 1e-6,
                              iterations != nullptr ? std::atoi(iterations) : 1000);
  btDeformableMultiBodyConstraintSolver constraint_solver;
  constraint_solver.setDeformableSolver(&deformable_solver);
  btDeformableMultiBodyDynamicsWorld world(&dispatcher, &broadphase, &constraint_solver,
                                           &configuration, &deformable_solver);
  const btVector3 gravity(0, 0, -9.81);
  world.setGravity(gravity);
  world.getWorldInfo().m_gravity = gravity;
  world.getWorldInfo().m_sparsesdf.Initialize();
  btSoftBody* body = btSoftBodyHelpers::CreateFromTetGenData(
      world.getWorldInfo(), ele.c_str(), nullptr, node.c_str(), false, true, true);
  if (body == nullptr || body->m_nodes.size() != static_cast<int>(mesh.vertex_count())) {
    std::fprintf(stderr, "Bullet did not accept the mesh\n");
    std::exit(2);
  }
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    body->setMass(static_cast<int>(i), model.masses()[i]);
  }
  for (VertexId v : bottom(mesh)) {
    body->setMass(v, 0.0);  // Bullet's way of holding a node
  }
  body->m_cfg.collisions = 0;  // no contact in this workload
  body->m_sleepingThreshold = 0;
  world.addSoftBody(body);
  world.setImplicit(true);
  world.setLineSearch(false);
  // Held nodes (zero mass) are projected out of the CG solve; without projection Bullet
  // switches to a Lagrange-multiplier solve in which the held block never moves.
  world.setUseProjection(true);
  deformable_solver.m_useProjection = true;
  const double mu = kYoung / (2.0 * (1.0 + kPoisson));
  const double lambda = kYoung * kPoisson / ((1.0 + kPoisson) * (1.0 - 2.0 * kPoisson));
  btDeformableLinearElasticityForce elasticity(mu, lambda, 0.0, 0.0);
  btDeformableGravityForce gravity_force(gravity);
  world.addForce(body, &elasticity);
  world.addForce(body, &gravity_force);
  BulletRun run;
  const auto start = Clock::now();
  const bool trace = std::getenv("INCISE_BENCH_TRACE") != nullptr;
  for (int s = 0; s < steps; ++s) {
    world.stepSimulation(kDt, 1, kDt);
    if (trace) {
      const VertexId c = top_centre(mesh);
      std::printf("bullet step %d: top centre z %.6f\n", s, body->m_nodes[c].m_x.z());
    }
  }
  run.ms_per_step = 1e3 * seconds_since(start) / steps;
  const VertexId centre = top_centre(mesh);
  run.sag = mesh.rest_position(centre).z() - body->m_nodes[centre].m_x.z();
  world.removeForce(body, &elasticity);
  world.removeForce(body, &gravity_force);
  world.removeSoftBody(body);
  delete body;
  return run;
}
#endif

/// STREAM-style triad a = b + s c over arrays far larger than the caches (GB/s, best of 5;
/// 24 bytes moved per element, as STREAM counts).
double triad_bandwidth() {
  const std::size_t n = std::size_t{1} << 24;
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  double best = 1e300;
  for (int repeat = 0; repeat < 5; ++repeat) {
    const auto start = Clock::now();
    for (std::size_t i = 0; i < n; ++i) {
      a[i] = b[i] + 3.0 * c[i];
    }
    best = std::min(best, seconds_since(start));
  }
  volatile double sink = a[n / 2];
  (void)sink;
  return 24.0 * static_cast<double>(n) / best / 1e9;
}

std::vector<int> parse_list(const char* text) {
  std::vector<int> values;
  std::string item;
  for (const char* c = text;; ++c) {
    if (*c == ',' || *c == '\0') {
      values.push_back(std::atoi(item.c_str()));
      item.clear();
      if (*c == '\0') {
        break;
      }
    } else {
      item += *c;
    }
  }
  return values;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes{10, 20};
  int steps = 100;
  int repeats = 2;
  bool variants = true;
  bool peer = true;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--cells") == 0 && i + 1 < argc) {
      sizes = parse_list(argv[++i]);
    } else if (std::strcmp(argv[i], "--steps") == 0 && i + 1 < argc) {
      steps = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--repeats") == 0 && i + 1 < argc) {
      repeats = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--no-variants") == 0) {
      variants = false;
    } else if (std::strcmp(argv[i], "--no-peer") == 0) {
      peer = false;
    } else {
      std::fprintf(
          stderr,
          "usage: %s [--cells 10,20] [--steps 100] [--repeats 2] [--no-variants] [--no-peer]\n",
          argv[0]);
      return 2;
    }
  }
  const double bandwidth = triad_bandwidth();
  std::printf("STREAM-style triad: %.1f GB/s\n\n", bandwidth);
  const IncisePlan standard{"assembled, block-Jacobi", incise::Preconditioner::kBlockJacobi, true};
  for (int cells : sizes) {
    std::printf("n = %d (%d tets), %d steps of %.2f s, best of %d alternating runs\n", cells,
                6 * cells * cells * cells, steps, kDt, repeats);
    InciseRun best_incise;
    best_incise.ms_per_step = 1e300;
#ifdef INCISE_WITH_BULLET
    BulletRun best_bullet;
    best_bullet.ms_per_step = 1e300;
#endif
    for (int r = 0; r < repeats; ++r) {
      const InciseRun incise = run_incise(cells, steps, standard);
      if (incise.ms_per_step < best_incise.ms_per_step) {
        best_incise = incise;
      }
#ifdef INCISE_WITH_BULLET
      if (peer) {
        const BulletRun bullet = run_bullet(cells, steps);
        if (bullet.ms_per_step < best_bullet.ms_per_step) {
          best_bullet = bullet;
        }
      }
#endif
    }
    std::printf("  %-34s %9.2f ms/step  sag %.3f mm  (%.1f CG iterations/step)\n", "incise",
                best_incise.ms_per_step, best_incise.sag * 1e3, best_incise.iterations_per_step);
#ifdef INCISE_WITH_BULLET
    if (peer) {
      std::printf("  %-34s %9.2f ms/step  sag %.3f mm\n", "Bullet 3.24 (double)",
                  best_bullet.ms_per_step, best_bullet.sag * 1e3);
      std::printf("  speed ratio Bullet / incise: %.2fx; sag difference %.2f %%\n",
                  best_bullet.ms_per_step / best_incise.ms_per_step,
                  100.0 * std::abs(best_incise.sag - best_bullet.sag) / best_bullet.sag);
    }
#else
    std::printf("  (Bullet peer not built: install libbullet-dev)\n");
#endif
    const InciseRun& b = best_incise;
    // The system matrix is assembled by the solver (assembly), then inverted block by block.
    const double other =
        b.total - b.forces - b.preconditioner - b.products - b.vector_updates - b.start;
    std::printf(
        "  incise time per step: forces with rotations and tangents %.2f ms, assembly %.2f "
        "ms, preconditioner %.2f ms, CG start from earlier solutions %.2f ms, CG products "
        "%.2f ms, CG vector updates %.2f ms, rest (set-up, right-hand side, integration) "
        "%.2f ms\n",
        1e3 * b.forces / steps, 1e3 * b.assembly / steps,
        1e3 * (b.preconditioner - b.assembly) / steps, 1e3 * b.start / steps,
        1e3 * b.products / steps, 1e3 * b.vector_updates / steps, 1e3 * other / steps);
    const double vertices = std::pow(cells + 1.0, 3.0);
    // One product streams the matrix (72 B values + 4 B column index per block) and about six
    // vertex-vector passes of 24 B (read p, write y, the mass and constraint passes).
    const double bytes = 76.0 * static_cast<double>(b.blocks) + 6.0 * 24.0 * vertices;
    const double product_ms = 1e3 * b.products / std::max(1.0, b.iterations_per_step * steps);
    std::printf(
        "  one CG product: %.3f ms measured, %.3f ms at triad bandwidth (%.1f MB moved)\n\n",
        product_ms, 1e3 * bytes / (bandwidth * 1e9), bytes / 1e6);
    if (variants) {
      for (const IncisePlan& plan :
           {IncisePlan{"matrix-free, block-Jacobi", incise::Preconditioner::kBlockJacobi, false},
            IncisePlan{"assembled, Jacobi", incise::Preconditioner::kJacobi, true},
            IncisePlan{"assembled, incomplete Cholesky",
                       incise::Preconditioner::kIncompleteCholesky, true},
            IncisePlan{"assembled, no preconditioner", incise::Preconditioner::kNone, true},
            IncisePlan{"block-Jacobi, extrapolated start", incise::Preconditioner::kBlockJacobi,
                       true, 0},
            IncisePlan{"block-Jacobi, double products", incise::Preconditioner::kBlockJacobi, true,
                       incise::LinearSolverOptions{}.start_history, false}}) {
        const InciseRun run = run_incise(cells, steps, plan);
        std::printf("  variant %-33s %9.2f ms/step  sag %.3f mm  (%.1f CG iterations/step)\n",
                    plan.name.c_str(), run.ms_per_step, run.sag * 1e3, run.iterations_per_step);
      }
      std::printf("\n");
    }
  }
  return 0;
}
