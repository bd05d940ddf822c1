// CG's preconditioners on the same matrices (issue 43, goal 4): incise's block-Jacobi and
// two-level preconditioners against hypre's BoomerAMG (libhypre-dev) as the preconditioner of
// hypre's PCG, and PETSc's GAMG (libpetsc-real-dev, where found) under PETSc's CG with the six
// rigid-body modes as its near-null space. The matrix is a backward-Euler step's, M + dt D + dt^2
// K, of the peers' box (0.1 m, n^3 cells, 6 tets per cell, corotational FEM, E = 3 kPa, nu = 0.45,
// rho = 1000 kg/m^3, z = 0 face held, gravity, dt = 0.01 s) linearised after five steps of
// sagging; the right-hand side is that step's dt f. Every solve starts from zero and stops at
// |r| / |b| <= 1e-6 (two-norm). incise's own CG is run through LinearizedSystemSolver exactly
// as the integrator runs it (single-precision products, no warm start); BoomerAMG runs on the
// same matrix, assembled here from the model and checked against incise's solution.
//
// usage: amg_compare [--cells 20,40] [--threads N] [--relax 8] [--aggressive 1] [--strong 0.5]
// --threads: incise's threads (default: every core). Debian's hypre 2.26 is built without
// OpenMP: one process runs it on one core (its parallelism is MPI ranks). --relax: BoomerAMG's
// smoother (8: l1 symmetric Gauss-Seidel, 6: hybrid symmetric Gauss-Seidel, 18: l1 Jacobi);
// --aggressive: levels of aggressive coarsening; --strong: the strength threshold.

#include <HYPRE.h>
#include <HYPRE_krylov.h>
#include <HYPRE_parcsr_ls.h>
#include <mpi.h>
#include <tbb/global_control.h>
#ifdef INCISE_WITH_PETSC
#include <petscksp.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/physics/block_sparse.hpp"
#include "incise/physics/boundary_conditions.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"
#include "incise/solve/linear_solvers.hpp"

namespace {

using namespace incise;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Row {
  std::string method;
  double setup_ms = 0.0;
  double solve_ms = 0.0;
  int iterations = 0;
  double residual = 0.0;  // |b - A x| / |b|, computed here on the exported matrix
};

/// The free unknowns' matrix in CSR (three scalar rows per free vertex), and its product.
struct ScalarMatrix {
  std::vector<int> free_index;  // vertex -> its first unknown, or -1 when held
  std::vector<HYPRE_Int> row_start, columns;
  std::vector<double> values;
  [[nodiscard]] HYPRE_Int size() const { return static_cast<HYPRE_Int>(row_start.size()) - 1; }
  [[nodiscard]] std::vector<double> times(const std::vector<double>& x) const {
    std::vector<double> y(x.size(), 0.0);
    for (HYPRE_Int i = 0; i < size(); ++i) {
      for (HYPRE_Int k = row_start[i]; k < row_start[i + 1]; ++k) {
        y[i] += values[k] * x[columns[k]];
      }
    }
    return y;
  }
};

ScalarMatrix scalar_matrix(const TetMesh& mesh, const MechanicalSystem& system,
                           std::span<const char> held, double a, double b) {
  BlockSparseMatrix matrix;
  matrix.build_pattern(mesh);
  if (!system.assemble_linearization(a, b, matrix)) {
    std::fprintf(stderr, "the system does not assemble its matrix\n");
    std::exit(1);
  }
  const std::span<const double> masses = system.masses();
  ScalarMatrix out;
  out.free_index.assign(mesh.vertex_count(), -1);
  int unknowns = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (held[v] == 0) {
      out.free_index[v] = unknowns;
      unknowns += 3;
    }
  }
  out.row_start.push_back(0);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (held[v] != 0) {
      continue;
    }
    const auto row = static_cast<VertexId>(v);
    const std::span<const VertexId> columns = matrix.row_columns(row);
    const std::size_t first = matrix.row_begin()[v];
    for (int i = 0; i < 3; ++i) {
      for (std::size_t k = 0; k < columns.size(); ++k) {
        const int column = out.free_index[static_cast<std::size_t>(columns[k])];
        if (column < 0) {
          continue;  // a held neighbour: its unknowns are zero
        }
        Mat3 block = matrix.values()[first + k];
        if (columns[k] == row) {
          block += masses[v] * Mat3::Identity();
        }
        for (int j = 0; j < 3; ++j) {
          out.columns.push_back(column + j);
          out.values.push_back(block(i, j));
        }
      }
      out.row_start.push_back(static_cast<HYPRE_Int>(out.columns.size()));
    }
  }
  return out;
}

double relative_residual(const ScalarMatrix& matrix, const std::vector<double>& rhs,
                         const std::vector<double>& x) {
  const std::vector<double> product = matrix.times(x);
  double r = 0.0;
  double b = 0.0;
  for (std::size_t i = 0; i < rhs.size(); ++i) {
    r += (rhs[i] - product[i]) * (rhs[i] - product[i]);
    b += rhs[i] * rhs[i];
  }
  return std::sqrt(r / b);
}

/// BoomerAMG-preconditioned PCG on the matrix; `nodal` picks nodal coarsening (the blocks of a
/// vertex coarsened together, by the Frobenius norm of each block) over the unknown approach.
struct AmgSettings {
  int relax = 8;
  int aggressive_levels = 1;  // fewer levels and cheaper cycles: measured best here
  double strong = 0.5;        // hypre's advice for 3-D elasticity
};

Row boomeramg(const ScalarMatrix& matrix, const std::vector<double>& rhs, bool nodal,
              const AmgSettings& settings) {
  const HYPRE_Int n = matrix.size();
  auto start = Clock::now();
  HYPRE_IJMatrix ij;
  HYPRE_IJMatrixCreate(MPI_COMM_WORLD, 0, n - 1, 0, n - 1, &ij);
  HYPRE_IJMatrixSetObjectType(ij, HYPRE_PARCSR);
  std::vector<HYPRE_Int> sizes(static_cast<std::size_t>(n));
  std::vector<HYPRE_Int> rows(static_cast<std::size_t>(n));
  for (HYPRE_Int i = 0; i < n; ++i) {
    sizes[i] = matrix.row_start[i + 1] - matrix.row_start[i];
    rows[i] = i;
  }
  HYPRE_IJMatrixSetRowSizes(ij, sizes.data());
  HYPRE_IJMatrixInitialize(ij);
  HYPRE_IJMatrixSetValues(ij, n, sizes.data(), rows.data(), matrix.columns.data(),
                          matrix.values.data());
  HYPRE_IJMatrixAssemble(ij);
  HYPRE_ParCSRMatrix parcsr;
  HYPRE_IJMatrixGetObject(ij, reinterpret_cast<void**>(&parcsr));
  const auto vector = [&](const std::vector<double>& values, HYPRE_IJVector& out) {
    HYPRE_IJVectorCreate(MPI_COMM_WORLD, 0, n - 1, &out);
    HYPRE_IJVectorSetObjectType(out, HYPRE_PARCSR);
    HYPRE_IJVectorInitialize(out);
    HYPRE_IJVectorSetValues(out, n, rows.data(), values.data());
    HYPRE_IJVectorAssemble(out);
    HYPRE_ParVector par;
    HYPRE_IJVectorGetObject(out, reinterpret_cast<void**>(&par));
    return par;
  };
  HYPRE_IJVector ij_b;
  HYPRE_IJVector ij_x;
  HYPRE_ParVector b = vector(rhs, ij_b);
  HYPRE_ParVector x = vector(std::vector<double>(rhs.size(), 0.0), ij_x);
  const double copy_ms = 1e3 * seconds_since(start);

  HYPRE_Solver pcg;
  HYPRE_Solver amg;
  HYPRE_ParCSRPCGCreate(MPI_COMM_WORLD, &pcg);
  HYPRE_PCGSetTol(pcg, 1e-6);
  HYPRE_PCGSetTwoNorm(pcg, 1);
  HYPRE_PCGSetMaxIter(pcg, 1000);
  HYPRE_BoomerAMGCreate(&amg);
  HYPRE_BoomerAMGSetNumFunctions(amg, 3);  // x, y, z of each vertex, interleaved
  if (nodal) {
    HYPRE_BoomerAMGSetNodal(amg, 4);  // coarsen vertices, strength by each block's norm
  }
  HYPRE_BoomerAMGSetStrongThreshold(amg, settings.strong);
  HYPRE_BoomerAMGSetCoarsenType(amg, 10);  // HMIS
  HYPRE_BoomerAMGSetInterpType(amg, 6);    // extended+i
  HYPRE_BoomerAMGSetPMaxElmts(amg, 4);
  HYPRE_BoomerAMGSetAggNumLevels(amg, settings.aggressive_levels);
  HYPRE_BoomerAMGSetRelaxType(amg, settings.relax);  // symmetric smoothers only: for CG
  HYPRE_BoomerAMGSetMaxIter(amg, 1);
  HYPRE_BoomerAMGSetTol(amg, 0.0);
  HYPRE_PCGSetPrecond(pcg, reinterpret_cast<HYPRE_PtrToSolverFcn>(HYPRE_BoomerAMGSolve),
                      reinterpret_cast<HYPRE_PtrToSolverFcn>(HYPRE_BoomerAMGSetup), amg);
  start = Clock::now();
  HYPRE_ParCSRPCGSetup(pcg, parcsr, b, x);
  const double setup_ms = 1e3 * seconds_since(start);
  start = Clock::now();
  HYPRE_ParCSRPCGSolve(pcg, parcsr, b, x);
  const double solve_ms = 1e3 * seconds_since(start);
  HYPRE_Int iterations = 0;
  HYPRE_PCGGetNumIterations(pcg, &iterations);
  std::vector<double> solution(rhs.size());
  HYPRE_IJVectorGetValues(ij_x, n, rows.data(), solution.data());
  Row row{nodal ? "BoomerAMG, nodal coarsening" : "BoomerAMG, unknown approach", setup_ms, solve_ms,
          static_cast<int>(iterations), relative_residual(matrix, rhs, solution)};
  std::fprintf(stderr, "  (copying the matrix into hypre: %.1f ms, not counted)\n", copy_ms);
  HYPRE_BoomerAMGDestroy(amg);
  HYPRE_ParCSRPCGDestroy(pcg);
  HYPRE_IJVectorDestroy(ij_x);
  HYPRE_IJVectorDestroy(ij_b);
  HYPRE_IJMatrixDestroy(ij);
  return row;
}

#ifdef INCISE_WITH_PETSC
/// PETSc's CG preconditioned by GAMG (smoothed aggregation) with the rigid-body modes of the
/// free vertices' positions (m) as its near-null space; the matrix in AIJ with block size 3.
Row gamg(const ScalarMatrix& matrix, const std::vector<double>& rhs,
         const std::vector<double>& coordinates) {
  const PetscInt n = matrix.size();
  const std::vector<PetscInt> row_start(matrix.row_start.begin(), matrix.row_start.end());
  const std::vector<PetscInt> columns(matrix.columns.begin(), matrix.columns.end());
  Mat a;
  MatCreate(PETSC_COMM_SELF, &a);
  MatSetSizes(a, n, n, n, n);
  MatSetType(a, MATSEQAIJ);
  MatSetBlockSize(a, 3);
  MatSeqAIJSetPreallocationCSR(a, row_start.data(), columns.data(), matrix.values.data());
  Vec coords;
  VecCreateSeq(PETSC_COMM_SELF, n, &coords);
  VecSetBlockSize(coords, 3);
  std::vector<PetscInt> rows(static_cast<std::size_t>(n));
  for (PetscInt i = 0; i < n; ++i) {
    rows[static_cast<std::size_t>(i)] = i;
  }
  VecSetValues(coords, n, rows.data(), coordinates.data(), INSERT_VALUES);
  VecAssemblyBegin(coords);
  VecAssemblyEnd(coords);
  MatNullSpace modes;
  MatNullSpaceCreateRigidBody(coords, &modes);
  MatSetNearNullSpace(a, modes);
  Vec b;
  Vec x;
  VecDuplicate(coords, &b);
  VecDuplicate(coords, &x);
  VecSetValues(b, n, rows.data(), rhs.data(), INSERT_VALUES);
  VecAssemblyBegin(b);
  VecAssemblyEnd(b);
  VecSet(x, 0.0);
  KSP ksp;
  KSPCreate(PETSC_COMM_SELF, &ksp);
  KSPSetOperators(ksp, a, a);
  KSPSetType(ksp, KSPCG);
  KSPSetNormType(ksp, KSP_NORM_UNPRECONDITIONED);  // |r| / |b|, as the others
  KSPSetTolerances(ksp, 1e-6, 0.0, PETSC_DEFAULT, 1000);
  PC pc;
  KSPGetPC(ksp, &pc);
  PCSetType(pc, PCGAMG);
  KSPSetFromOptions(ksp);  // -pc_gamg_* options may tune it
  auto start = Clock::now();
  KSPSetUp(ksp);
  PCSetUp(pc);
  const double setup_ms = 1e3 * seconds_since(start);
  start = Clock::now();
  KSPSolve(ksp, b, x);
  const double solve_ms = 1e3 * seconds_since(start);
  PetscInt iterations = 0;
  KSPGetIterationNumber(ksp, &iterations);
  std::vector<double> solution(rhs.size());
  VecGetValues(x, n, rows.data(), solution.data());
  Row row{"PETSc GAMG, rigid-body modes", setup_ms, solve_ms, static_cast<int>(iterations),
          relative_residual(matrix, rhs, solution)};
  KSPDestroy(&ksp);
  VecDestroy(&x);
  VecDestroy(&b);
  MatNullSpaceDestroy(&modes);
  VecDestroy(&coords);
  MatDestroy(&a);
  return row;
}
#endif

void compare(int cells, const AmgSettings& settings) {
  BoxGridOptions grid;
  grid.cells = {cells, cells, cells};
  grid.size = Vec3(0.1, 0.1, 0.1);  // m
  TetMesh mesh = make_box_grid(grid);
  Material material;
  material.young_modulus = 3000.0;  // Pa
  material.poisson_ratio = 0.45;
  material.density = 1000.0;  // kg/m^3
  CorotationalFemModel model(mesh, material);
  BoundaryConditions conditions(mesh);
  conditions.fix(vertices_in_box(mesh, Vec3(-1, -1, -1), Vec3(1, 1, 1e-9)));
  conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  MechanicalSystem system(mesh, model, conditions);
  SimulationState state(mesh);
  const double dt = 0.01;  // s
  BackwardEulerOptions stepping;
  stepping.solver.tolerance = 1e-6;
  BackwardEuler integrator(stepping);
  for (int step = 0; step < 5; ++step) {  // the body sags and its elements rotate
    integrator.step(system, state.x.values(), state.v.values(), dt * step, dt);
  }
  const std::size_t vertices = mesh.vertex_count();
  std::vector<char> held(vertices, 0);
  for (std::size_t v = 0; v < vertices; ++v) {
    held[v] = system.is_constrained(static_cast<VertexId>(v)) ? 1 : 0;
  }
  const double t = 5 * dt;
  std::vector<Vec3> force(vertices, Vec3::Zero());
  system.forces(t, state.x.values(), state.v.values(), force);
  system.prepare_linearization(t, state.x.values(), state.v.values());
  std::vector<Vec3> rhs(vertices, Vec3::Zero());
  for (std::size_t v = 0; v < vertices; ++v) {
    rhs[v] = held[v] != 0 ? Vec3::Zero() : Vec3(dt * force[v]);
  }
  const ScalarMatrix matrix = scalar_matrix(mesh, system, held, dt * dt, dt);
  std::vector<double> scalar_rhs;
  for (std::size_t v = 0; v < vertices; ++v) {
    if (held[v] == 0) {
      scalar_rhs.insert(scalar_rhs.end(), {rhs[v].x(), rhs[v].y(), rhs[v].z()});
    }
  }
  std::printf("\n%d^3 cells: %zu tets, %d free unknowns, %zu nonzeros\n", cells, mesh.tet_count(),
              matrix.size(), matrix.values.size());
  std::printf(
      "| preconditioner | set-up ms | solve ms | total ms | CG iterations | ms per iteration "
      "| |b - A x| / |b| |\n|---|---|---|---|---|---|---|\n");
  const auto print = [](const Row& row) {
    std::printf("| %s | %.1f | %.1f | %.1f | %d | %.2f | %.1e |\n", row.method.c_str(),
                row.setup_ms, row.solve_ms, row.setup_ms + row.solve_ms, row.iterations,
                row.iterations > 0 ? row.solve_ms / row.iterations : 0.0, row.residual);
    std::fflush(stdout);
  };
  for (Preconditioner preconditioner : {Preconditioner::kBlockJacobi, Preconditioner::kTwoLevel}) {
    LinearSolverOptions options;
    options.preconditioner = preconditioner;
    options.tolerance = 1e-6;
    options.max_iterations = 2000;
    options.warm_start = false;
    options.start_history = 0;
    // Twice: the first solve also builds the pattern-dependent parts once (as the first frame
    // does); the second is what a frame pays.
    LinearSolveStats stats;
    std::vector<Vec3> x(vertices, Vec3::Zero());
    for (int run = 0; run < 2; ++run) {
      LinearizedSystemSolver solver(options);
      solver.set_linearization_positions(state.x.values());
      std::fill(x.begin(), x.end(), Vec3::Zero());
      if (run == 1) {
        (void)solver.solve(system, 1.0, dt * dt, dt, held, rhs, x);
        std::fill(x.begin(), x.end(), Vec3::Zero());
      }
      stats = solver.solve(system, 1.0, dt * dt, dt, held, rhs, x);
    }
    std::vector<double> solution;
    for (std::size_t v = 0; v < vertices; ++v) {
      if (held[v] == 0) {
        solution.insert(solution.end(), {x[v].x(), x[v].y(), x[v].z()});
      }
    }
    // The preconditioner's set-up; the assembly of the matrix is left out of both sides.
    print({"incise " + to_string(preconditioner), 1e3 * stats.seconds_preconditioner,
           1e3 * (stats.seconds_products + stats.seconds_vector_updates), stats.iterations,
           relative_residual(matrix, scalar_rhs, solution)});
  }
  print(boomeramg(matrix, scalar_rhs, true, settings));
  print(boomeramg(matrix, scalar_rhs, false, settings));
#ifdef INCISE_WITH_PETSC
  std::vector<double> coordinates;  // m, the free vertices' positions where linearised
  for (std::size_t v = 0; v < vertices; ++v) {
    if (held[v] == 0) {
      const Vec3& p = state.x.values()[v];
      coordinates.insert(coordinates.end(), {p.x(), p.y(), p.z()});
    }
  }
  print(gamg(matrix, scalar_rhs, coordinates));
#endif
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  HYPRE_Init();
#ifdef INCISE_WITH_PETSC
  PetscInitializeNoArguments();
#endif
  std::vector<int> sizes{20, 40};
  AmgSettings settings;
  std::unique_ptr<tbb::global_control> threads;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--threads") == 0) {
      threads = incise::bench::thread_limit(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--relax") == 0) {
      settings.relax = std::atoi(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--aggressive") == 0) {
      settings.aggressive_levels = std::atoi(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--strong") == 0) {
      settings.strong = std::atof(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--cells") == 0) {
      sizes = incise::bench::comma_separated_ints(argv[i + 1]);
    }
  }
  for (int cells : sizes) {
    compare(cells, settings);
  }
#ifdef INCISE_WITH_PETSC
  PetscFinalize();
#endif
  HYPRE_Finalize();
  MPI_Finalize();
  return 0;
}
