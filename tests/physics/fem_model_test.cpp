// The corotational FEM model on meshes: consistency of its products and forces, damping,
// material fractions, edits, determinism across thread counts, and accuracy against
// analytical solutions (patch test, uniaxial tension, cantilever beam, the peers' box).

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mass_spring.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"

namespace incise {
namespace {

Material material(double young, double poisson, double density) {
  Material m;
  m.young_modulus = young;
  m.poisson_ratio = poisson;
  m.density = density;
  return m;
}

/// A box grid with its model, boundary conditions, system and state, built in place.
struct Body {
  Body(const BoxGridOptions& grid, const Material& tissue,
       const CorotationalFemParameters& parameters = {})
      : mesh(make_box_grid(grid)),
        model(mesh, tissue, parameters),
        conditions(mesh),
        system(mesh, model, conditions),
        state(mesh) {}
  TetMesh mesh;
  CorotationalFemModel model;
  BoundaryConditions conditions;
  MechanicalSystem system;
  SimulationState state;
};

BoxGridOptions box(std::array<int, 3> cells, const Vec3& size) {
  BoxGridOptions options;
  options.cells = cells;
  options.size = size;
  return options;
}

std::vector<Vec3> random_field(std::size_t n, double amplitude, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-amplitude, amplitude);
  std::vector<Vec3> field(n);
  for (Vec3& v : field) {
    v = Vec3(uniform(random), uniform(random), uniform(random));
  }
  return field;
}

double max_difference(std::span<const Vec3> a, std::span<const Vec3> b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    worst = std::max(worst, (a[i] - b[i]).norm());
  }
  return worst;
}

double max_norm(std::span<const Vec3> a) {
  double worst = 0.0;
  for (const Vec3& v : a) {
    worst = std::max(worst, v.norm());
  }
  return worst;
}

/// Prepares the body's linearisation at a sheared state (away from rest, so the rotations
/// matter), at rest velocities.
void linearize_sheared(Body& body) {
  const auto rest = body.state.x.values();
  std::vector<Vec3> x(rest.begin(), rest.end());
  for (Vec3& p : x) {
    p += Vec3(0.002 * p.z(), 0.0, -0.001 * p.x());
  }
  body.system.prepare_linearization(0.0, x, std::vector<Vec3>(x.size(), Vec3::Zero()));
}

/// The solver's flags of the held rows.
std::vector<char> held_rows(const Body& body) {
  std::vector<char> constrained(body.mesh.vertex_count(), 0);
  for (std::size_t i = 0; i < constrained.size(); ++i) {
    constrained[i] = body.system.is_constrained(static_cast<VertexId>(i)) ? 1 : 0;
  }
  return constrained;
}

TEST(FemModel, MassIsDensityTimesVolumeAndRestIsForceFree) {
  Body body(box({3, 2, 2}, Vec3(0.03, 0.02, 0.02)), material(3e3, 0.45, 1000.0));
  EXPECT_NEAR(body.model.total_mass(), 1000.0 * 0.03 * 0.02 * 0.02, 1e-15);
  double lumped = 0.0;
  for (double m : body.model.masses()) {
    lumped += m;
  }
  EXPECT_NEAR(lumped, body.model.total_mass(), 1e-15);
  std::vector<Vec3> f(body.mesh.vertex_count(), Vec3::Zero());
  const std::vector<Vec3> v(body.mesh.vertex_count(), Vec3::Zero());
  body.model.add_forces(body.state.x.values(), v, f);
  EXPECT_LT(max_norm(f), 1e-15);
}

TEST(FemModel, AssembledAndMatrixFreeProductsAgreeWithForceDifferences) {
  for (TangentKind kind : {TangentKind::kWarped, TangentKind::kProjected, TangentKind::kExact}) {
    CorotationalFemParameters parameters;
    parameters.tangent = kind;
    Body body(box({3, 3, 2}, Vec3(0.03, 0.03, 0.02)), material(3e3, 0.45, 1000.0), parameters);
    const std::size_t n = body.mesh.vertex_count();
    std::vector<Vec3> x(body.state.x.values().begin(), body.state.x.values().end());
    const std::vector<Vec3> displacement = random_field(n, 0.002, 1);
    for (std::size_t i = 0; i < n; ++i) {
      x[i] += displacement[i];
    }
    const std::vector<Vec3> v(n, Vec3::Zero());
    const std::vector<Vec3> p = random_field(n, 1.0, 2);
    body.model.set_assemble(true);
    body.model.prepare_linearization(x, v);
    std::vector<Vec3> assembled(n, Vec3::Zero());
    body.model.add_linearized_product(1.0, 0.0, p, assembled);
    body.model.set_assemble(false);
    body.model.prepare_linearization(x, v);
    std::vector<Vec3> matrix_free(n, Vec3::Zero());
    body.model.add_linearized_product(1.0, 0.0, p, matrix_free);
    const double scale = max_norm(assembled);
    EXPECT_LT(max_difference(assembled, matrix_free), 1e-12 * scale);
    // The assembled block matrix holds the same operator.
    BlockSparseMatrix matrix;
    ASSERT_TRUE(body.model.assemble_linearization(1.0, 0.0, matrix));
    std::vector<Vec3> product(n);
    matrix.multiply(p, product);
    EXPECT_LT(max_difference(product, assembled), 1e-12 * scale);
    if (kind == TangentKind::kExact) {
      // K p = -(f(x + h p) - f(x - h p)) / 2h.
      const double h = 1e-7;
      std::vector<Vec3> plus(x), minus(x), f_plus(n, Vec3::Zero()), f_minus(n, Vec3::Zero());
      for (std::size_t i = 0; i < n; ++i) {
        plus[i] += h * p[i];
        minus[i] -= h * p[i];
      }
      body.model.add_forces(plus, v, f_plus);
      body.model.add_forces(minus, v, f_minus);
      std::vector<Vec3> numeric(n);
      for (std::size_t i = 0; i < n; ++i) {
        numeric[i] = -(f_plus[i] - f_minus[i]) / (2.0 * h);
      }
      EXPECT_LT(max_difference(numeric, assembled), 1e-6 * scale);
    }
  }
}

TEST(FemModel, RayleighDampingForceIsAlphaMPlusBetaK) {
  CorotationalFemParameters parameters;
  parameters.rayleigh_mass = 0.7;
  parameters.rayleigh_stiffness = 0.03;
  Body body(box({2, 2, 2}, Vec3(0.02, 0.02, 0.02)), material(3e3, 0.45, 1000.0), parameters);
  const std::size_t n = body.mesh.vertex_count();
  const std::vector<Vec3> x(body.state.x.values().begin(), body.state.x.values().end());
  const std::vector<Vec3> v = random_field(n, 0.1, 3);
  std::vector<Vec3> f(n, Vec3::Zero());
  body.model.add_forces(x, v, f);
  body.model.prepare_linearization(x, v);
  std::vector<Vec3> expected(n, Vec3::Zero());
  body.model.add_linearized_product(0.0, 1.0, v, expected);  // D v
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_LT((f[i] + expected[i]).norm(), 1e-12 * max_norm(expected));
  }
}

TEST(FemModel, MaterialFractionScalesForcesAndMass) {
  Body full(box({2, 2, 1}, Vec3(0.02, 0.02, 0.01)), material(3e3, 0.45, 1000.0));
  Body half(box({2, 2, 1}, Vec3(0.02, 0.02, 0.01)), material(3e3, 0.45, 1000.0));
  for (std::size_t t = 0; t < half.mesh.tet_count(); ++t) {
    half.model.set_material_fraction(static_cast<TetId>(t), 0.5);
  }
  half.model.refresh();
  EXPECT_NEAR(half.model.total_mass(), 0.5 * full.model.total_mass(), 1e-15);
  const std::size_t n = full.mesh.vertex_count();
  std::vector<Vec3> x(full.state.x.values().begin(), full.state.x.values().end());
  const std::vector<Vec3> d = random_field(n, 0.001, 4);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] += d[i];
  }
  const std::vector<Vec3> v(n, Vec3::Zero());
  std::vector<Vec3> f_full(n, Vec3::Zero()), f_half(n, Vec3::Zero());
  full.model.add_forces(x, v, f_full);
  half.model.add_forces(x, v, f_half);
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_LT((f_half[i] - 0.5 * f_full[i]).norm(), 1e-14 * max_norm(f_full));
    EXPECT_NEAR(half.model.masses()[i], 0.5 * full.model.masses()[i], 1e-18);
  }
  EXPECT_THROW(half.model.set_material_fraction(0, 1.5), InputError);
}

TEST(FemModel, FollowsSplitsWithMassConservedAndRestStillForceFree) {
  Body body(box({2, 2, 2}, Vec3(0.02, 0.02, 0.02)), material(3e3, 0.45, 1000.0));
  const double mass = body.model.total_mass();
  std::mt19937 random(5);
  for (int edit = 0; edit < 30; ++edit) {
    const auto tet = static_cast<TetId>(random() % body.mesh.tet_count());
    (void)split_tet(body.mesh, tet, {0.25, 0.25, 0.25, 0.25});
  }
  body.model.refresh();
  EXPECT_NEAR(body.model.total_mass(), mass, 1e-15);
  double lumped = 0.0;
  for (double m : body.model.masses()) {
    lumped += m;
  }
  EXPECT_NEAR(lumped, mass, 1e-15);
  const std::size_t n = body.mesh.vertex_count();
  std::vector<Vec3> f(n, Vec3::Zero());
  const std::vector<Vec3> v(n, Vec3::Zero());
  body.model.add_forces(body.state.x.values(), v, f);
  EXPECT_LT(max_norm(f), 1e-15);
  // A stretch gives the same total elastic energy whatever the subdivision (F is constant).
  Body reference(box({2, 2, 2}, Vec3(0.02, 0.02, 0.02)), material(3e3, 0.45, 1000.0));
  auto stretched = [](const TetMesh& mesh) {
    std::vector<Vec3> x(mesh.vertex_count());
    for (std::size_t i = 0; i < x.size(); ++i) {
      x[i] = mesh.rest_position(static_cast<VertexId>(i)).cwiseProduct(Vec3(1.1, 0.95, 1.0));
    }
    return x;
  };
  EXPECT_NEAR(body.model.elastic_energy(stretched(body.mesh)),
              reference.model.elastic_energy(stretched(reference.mesh)),
              1e-12 * reference.model.elastic_energy(stretched(reference.mesh)));
}

TEST(FemModel, EditsLeaveThePerElementArraysWhereTheyAreUntilTheBodyHasDoubled) {
  // A long cutting session adds tetrahedra and vertices frame after frame. An array that
  // outgrows its capacity is copied into fresh pages within a frame: with a quarter more
  // capacity, a session that cut the 50k body through twice copied them at every quarter it
  // added (BENCHMARKS.md). The mesh's, the state's and the model's arrays stay put until the
  // body has doubled.
  Body body(box({4, 4, 4}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0));
  const std::size_t tets = body.mesh.tet_count();
  const std::size_t vertices = body.mesh.vertex_count();
  linearize_sheared(body);
  const Tet* mesh_tets = body.mesh.tets().data();
  const Vec3* rest_positions = body.mesh.rest_positions().data();
  const Vec3* positions = body.state.x.values().data();
  const double* masses = body.model.masses().data();
  std::mt19937 random(7);
  while (body.mesh.tet_count() + 3 < 2 * tets && body.mesh.vertex_count() + 1 < 2 * vertices) {
    const auto tet = static_cast<TetId>(random() % body.mesh.tet_count());
    (void)split_tet(body.mesh, tet, {0.25, 0.25, 0.25, 0.25});
    body.model.refresh();
    ASSERT_EQ(body.mesh.tets().data(), mesh_tets) << "at " << body.mesh.tet_count() << " tets";
    ASSERT_EQ(body.mesh.rest_positions().data(), rest_positions)
        << "at " << body.mesh.vertex_count() << " vertices";
    ASSERT_EQ(body.state.x.values().data(), positions)
        << "at " << body.mesh.vertex_count() << " vertices";
    ASSERT_EQ(body.model.masses().data(), masses)
        << "at " << body.mesh.vertex_count() << " vertices";
  }
  EXPECT_GT(body.mesh.tet_count(), tets + 3 * tets / 4) << "the test did not reach that far";
}

/// Vertices whose rest coordinate `axis` equals `value` (to rounding).
std::vector<VertexId> at_plane(const TetMesh& mesh, int axis, double value) {
  std::vector<VertexId> vertices;
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    if (std::abs(mesh.rest_position(static_cast<VertexId>(i))[axis] - value) < 1e-9) {
      vertices.push_back(static_cast<VertexId>(i));
    }
  }
  return vertices;
}

std::vector<Vec3> run_steps(int threads, int steps) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<std::size_t>(threads));
  CorotationalFemParameters parameters;
  parameters.rayleigh_stiffness = 0.01;
  Body body(box({6, 6, 6}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0), parameters);
  body.conditions.fix(at_plane(body.mesh, 2, 0.0));
  body.conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  BackwardEulerOptions options;
  options.solver.tolerance = 1e-6;
  BackwardEuler integrator(options);
  for (int s = 0; s < steps; ++s) {
    integrator.step(body.system, body.state.x.values(), body.state.v.values(), s * 0.01, 0.01);
  }
  return {body.state.x.values().begin(), body.state.x.values().end()};
}

TEST(FemModel, SameResultWhateverTheThreadCount) {
  const std::vector<Vec3> one = run_steps(1, 10);
  const std::vector<Vec3> two = run_steps(2, 10);
  const std::vector<Vec3> four = run_steps(4, 10);
  ASSERT_EQ(one.size(), two.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i], two[i]) << "vertex " << i;  // bit-identical
    EXPECT_EQ(one[i], four[i]) << "vertex " << i;
  }
}

// ---- accuracy -----------------------------------------------------------------------------

StaticOptions direct_static() {
  StaticOptions options;
  options.tolerance = 1e-7;
  options.solver.type = LinearSolverType::kDirect;
  return options;
}

TEST(FemAccuracy, PatchTestReproducesAffineFieldsExactly) {
  // Boundary vertices follow x = A X + b (a finite rotation times a stretch); the free
  // interior must land on the same field, whatever the mesh.
  for (int tets_per_cell : {5, 6}) {
    BoxGridOptions grid = box({4, 3, 3}, Vec3(0.04, 0.03, 0.03));
    grid.tets_per_cell = tets_per_cell;
    Body body(grid, material(3e3, 0.45, 1000.0));
    const Mat3 rotation =
        Eigen::AngleAxisd(0.6, Vec3(1.0, 2.0, 0.5).normalized()).toRotationMatrix();
    Mat3 stretch;
    stretch << 1.05, 0.02, 0.0, 0.02, 0.97, 0.01, 0.0, 0.01, 1.02;
    const Mat3 A = rotation * stretch;
    const Vec3 b(0.01, -0.02, 0.005);
    std::vector<char> on_boundary(body.mesh.vertex_count(), 0);
    for (int axis = 0; axis < 3; ++axis) {
      for (double value : {0.0, grid.size[axis]}) {
        for (VertexId v : at_plane(body.mesh, axis, value)) {
          on_boundary[v] = 1;
        }
      }
    }
    int interior = 0;
    for (std::size_t i = 0; i < on_boundary.size(); ++i) {
      const Vec3& X = body.mesh.rest_position(static_cast<VertexId>(i));
      if (on_boundary[i] != 0) {
        const VertexId vertex = static_cast<VertexId>(i);
        body.conditions.prescribe_displacement({&vertex, 1}, A * X + b - X, 0.0);
      } else {
        ++interior;
      }
    }
    ASSERT_GT(interior, 0);
    StaticOptions options = direct_static();
    options.tolerance = 1e-14;  // to rounding: the answer is exact
    options.max_iterations = 12;
    StaticEquilibrium solver(options);
    (void)solver.solve(body.system, body.state.x.values(), 0.0);
    for (std::size_t i = 0; i < on_boundary.size(); ++i) {
      const Vec3 exact = A * body.mesh.rest_position(static_cast<VertexId>(i)) + b;
      // 1e-11 m on a 0.04 m patch: rounding.
      EXPECT_LT((body.state.x[static_cast<VertexId>(i)] - exact).norm(), 1e-11) << "vertex " << i;
    }
  }
}

TEST(FemAccuracy, UniaxialTensionGivesYoungsModulusAndPoissonsRatio) {
  const double young = 5.0e4;  // Pa
  const double poisson = 0.3;
  const double length = 0.1;
  const double width = 0.02;
  Body body(box({30, 6, 6}, Vec3(length, width, width)), material(young, poisson, 1000.0),
            {0.0, 0.0, TangentKind::kProjected, true});
  body.conditions.fix(at_plane(body.mesh, 0, 0.0));
  const double stress = 0.01 * young;  // nominal, for 1 % strain
  body.conditions.add_force(at_plane(body.mesh, 0, length), Vec3(stress * width * width, 0, 0));
  StaticEquilibrium solver(direct_static());
  ASSERT_TRUE(solver.solve(body.system, body.state.x.values(), 0.0));
  // Away from the ends (Saint-Venant): mean axial strain between two sections, and the
  // lateral contraction at mid-length.
  auto mean = [&](const std::vector<VertexId>& vertices, int axis) {
    double sum = 0.0;
    for (VertexId v : vertices) {
      sum += body.state.x[v][axis];
    }
    return sum / static_cast<double>(vertices.size());
  };
  const double x1 = 0.3 * length;
  const double x2 = 0.7 * length;
  const double axial =
      (mean(at_plane(body.mesh, 0, x2), 0) - mean(at_plane(body.mesh, 0, x1), 0)) / (x2 - x1) - 1.0;
  std::vector<VertexId> low_side;
  std::vector<VertexId> high_side;
  for (VertexId v : at_plane(body.mesh, 0, 0.5 * length)) {
    const double y = body.mesh.rest_position(v).y();
    if (std::abs(y) < 1e-9) {
      low_side.push_back(v);
    } else if (std::abs(y - width) < 1e-9) {
      high_side.push_back(v);
    }
  }
  const double lateral = (mean(high_side, 1) - mean(low_side, 1)) / width - 1.0;
  const double measured_young = stress / axial;
  const double measured_poisson = -lateral / axial;
  std::printf("uniaxial: E %.1f Pa (expected %.1f), nu %.4f (expected %.2f)\n", measured_young,
              young, measured_poisson, poisson);
  EXPECT_NEAR(measured_young, young, 0.02 * young);
  EXPECT_NEAR(measured_poisson, poisson, 0.02);
}

/// Tip deflection (m) of a gravity-loaded cantilever, L = 10 h, meshed with n x n/10 x n/10
/// cells.
double cantilever_deflection(int cells_along, double young, double density, int across = -1,
                             double poisson = 0.3, int tets_per_cell = 6) {
  const double length = 0.1;
  const double height = 0.01;
  if (across < 0) {
    across = cells_along / 10;
  }
  BoxGridOptions grid = box({cells_along, across, across}, Vec3(length, height, height));
  grid.tets_per_cell = tets_per_cell;
  Body body(grid, material(young, poisson, density), {0.0, 0.0, TangentKind::kProjected, true});
  body.conditions.fix(at_plane(body.mesh, 0, 0.0));
  body.conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  StaticEquilibrium solver(direct_static());
  EXPECT_TRUE(solver.solve(body.system, body.state.x.values(), 0.0))
      << solver.last_iterations() << " iterations, residual " << solver.last_residual();
  double sum = 0.0;
  const std::vector<VertexId> tip = at_plane(body.mesh, 0, length);
  for (VertexId v : tip) {
    sum += body.state.x[v].z() - body.mesh.rest_position(v).z();
  }
  return -sum / static_cast<double>(tip.size());
}

TEST(FemAccuracy, CantileverConvergesToEulerBernoulli) {
  const double young = 1.0e7;  // Pa: a small (1.5 %) deflection, where beam theory holds
  const double density = 1000.0;
  const double length = 0.1;
  const double height = 0.01;
  const double load = density * 9.81 * height * height;  // N/m
  const double inertia = std::pow(height, 4) / 12.0;     // m^4
  const double exact = load * std::pow(length, 4) / (8.0 * young * inertia);
  double previous_error = 1.0;
  // Five tetrahedra per cell: the six-tet split is stiffer in bending (20.7 % vs 8.0 % error
  // at 40 x 4 x 4 cells).
  for (int cells : {20, 40, 80}) {
    const double deflection = cantilever_deflection(cells, young, density, cells / 10, 0.3, 5);
    const double error = std::abs(deflection - exact) / exact;
    std::printf(
        "cantilever %2d x %d x %d cells (%5d tets): tip %.4f mm, Euler-Bernoulli %.4f mm, "
        "error %.1f %%\n",
        cells, cells / 10, cells / 10, 5 * cells * (cells / 10) * (cells / 10), deflection * 1e3,
        exact * 1e3, 100.0 * error);
    EXPECT_LT(error, previous_error) << "refinement must reduce the error";
    previous_error = error;
  }
  EXPECT_LT(previous_error, 0.05);
}

TEST(FemAccuracy, StaticSolversAgreeAndAutoFactorisesSlenderBodies) {
  // A slender cantilever (80 x 2 x 2 cells, L = 10 h): block-Jacobi CG gives inexact Newton
  // steps here; the factorised steps of "direct" and "auto" converge in a few iterations.
  double tips[3] = {};
  const LinearSolverType types[3] = {LinearSolverType::kConjugateGradient,
                                     LinearSolverType::kDirect, LinearSolverType::kAuto};
  for (int k = 0; k < 3; ++k) {
    BoxGridOptions grid = box({80, 2, 2}, Vec3(0.1, 0.01, 0.01));
    Body body(grid, material(1e7, 0.3, 1000.0), {0.0, 0.0, TangentKind::kProjected, true});
    body.conditions.fix(at_plane(body.mesh, 0, 0.0));
    body.conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
    StaticOptions options;
    options.solver.type = types[k];
    StaticEquilibrium solver(options);
    const bool converged = solver.solve(body.system, body.state.x.values(), 0.0);
    for (VertexId v : at_plane(body.mesh, 0, 0.1)) {
      tips[k] = std::max(tips[k], body.mesh.rest_position(v).z() - body.state.x[v].z());
    }
    if (types[k] != LinearSolverType::kConjugateGradient) {
      EXPECT_TRUE(converged) << "residual " << solver.last_residual();
      EXPECT_LE(solver.last_iterations(), 10);
      EXPECT_TRUE(solver.last_solve_direct()) << "auto factorises a body this small";
      EXPECT_EQ(solver.last_linear_iterations(), solver.last_iterations());
    } else {
      EXPECT_FALSE(solver.last_solve_direct());
    }
  }
  EXPECT_GT(tips[1], 5e-4);  // m: the body bends
  EXPECT_NEAR(tips[0], tips[1], 1e-6 * tips[1]);
  EXPECT_NEAR(tips[2], tips[1], 1e-9 * tips[1]);
}

/// The peers' workload: a 0.1 m cube of n^3 cells, z = 0 fixed, gravity, dt = 0.01 s.
double peer_box_sag(int cells, int steps, const LinearSolverOptions& solver, bool& finite) {
  Body body(box({cells, cells, cells}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0));
  body.conditions.fix(at_plane(body.mesh, 2, 0.0));
  body.conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  BackwardEulerOptions options;
  options.solver = solver;
  BackwardEuler integrator(options);
  finite = true;
  for (int s = 0; s < steps; ++s) {
    integrator.step(body.system, body.state.x.values(), body.state.v.values(), s * 0.01, 0.01);
    for (const Vec3& x : body.state.x.values()) {
      finite = finite && x.allFinite();
    }
  }
  // Sag: displacement of the top face's centre vertex.
  VertexId centre = 0;
  double best = 1e300;
  for (std::size_t i = 0; i < body.mesh.vertex_count(); ++i) {
    const double d =
        (body.mesh.rest_position(static_cast<VertexId>(i)) - Vec3(0.05, 0.05, 0.1)).norm();
    if (d < best) {
      best = d;
      centre = static_cast<VertexId>(i);
    }
  }
  return body.mesh.rest_position(centre).z() - body.state.x[centre].z();
}

TEST(FemAccuracy, PeerBoxStaysStableFor1000StepsAndMatchesTheDirectSolver) {
  LinearSolverOptions cg;
  cg.tolerance = 1e-6;
  cg.preconditioner = Preconditioner::kBlockJacobi;
  LinearSolverOptions direct;
  direct.type = LinearSolverType::kDirect;
  bool cg_finite = false;
  bool direct_finite = false;
  // 1000 steps (10 s) with CG: backward Euler has settled at equilibrium, which the direct
  // solver gives as the static reference; and 100 steps with each solver follow one trajectory.
  const double sag = peer_box_sag(10, 1000, cg, cg_finite);
  Body body(box({10, 10, 10}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0),
            {0.0, 0.0, TangentKind::kProjected, true});
  body.conditions.fix(at_plane(body.mesh, 2, 0.0));
  body.conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
  StaticEquilibrium solver(direct_static());
  ASSERT_TRUE(solver.solve(body.system, body.state.x.values(), 0.0));
  const std::vector<VertexId> top = at_plane(body.mesh, 2, 0.1);
  VertexId centre = top.front();
  for (VertexId v : top) {
    if ((body.mesh.rest_position(v) - Vec3(0.05, 0.05, 0.1)).norm() <
        (body.mesh.rest_position(centre) - Vec3(0.05, 0.05, 0.1)).norm()) {
      centre = v;
    }
  }
  const double reference = body.mesh.rest_position(centre).z() - body.state.x[centre].z();
  const double early_cg = peer_box_sag(10, 100, cg, cg_finite);
  const double early_direct = peer_box_sag(10, 100, direct, direct_finite);
  std::printf(
      "peer box n = 10: sag %.3f mm after 1000 steps (CG), %.3f mm static (direct); "
      "after 100 steps %.4f mm (CG), %.4f mm (direct)\n",
      sag * 1e3, reference * 1e3, early_cg * 1e3, early_direct * 1e3);
  EXPECT_TRUE(cg_finite);
  EXPECT_TRUE(direct_finite);
  EXPECT_GT(sag, 0.0);
  EXPECT_NEAR(sag, reference, 0.01 * reference);
  EXPECT_NEAR(early_cg, early_direct, 0.01 * early_direct);
}

TEST(FemAccuracy, PreconditionersAndDirectSolverAgreeOnOneStep) {
  std::vector<double> sags;
  for (Preconditioner preconditioner :
       {Preconditioner::kNone, Preconditioner::kJacobi, Preconditioner::kBlockJacobi,
        Preconditioner::kIncompleteCholesky, Preconditioner::kTwoLevel}) {
    LinearSolverOptions options;
    options.tolerance = 1e-10;
    options.preconditioner = preconditioner;
    bool finite = false;
    sags.push_back(peer_box_sag(4, 5, options, finite));
    EXPECT_TRUE(finite);
    std::printf("%s: sag %.9f mm\n", to_string(preconditioner).c_str(), sags.back() * 1e3);
  }
  LinearSolverOptions direct;
  direct.type = LinearSolverType::kDirect;
  bool finite = false;
  const double reference = peer_box_sag(4, 5, direct, finite);
  for (double sag : sags) {
    EXPECT_NEAR(sag, reference, 1e-8 * std::abs(reference));
  }
}

/// The solver tests' system: a 4x4x4 box held at z = 0, linearised at a sheared state, with a
/// random load (the same in every test that takes it).
struct ShearedSystem {
  ShearedSystem() : body(box({4, 4, 4}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0)) {
    body.conditions.fix(at_plane(body.mesh, 2, 0.0));
    linearize_sheared(body);
    n = body.mesh.vertex_count();
    constrained = held_rows(body);
    rhs = random_field(n, 1e-3, 7);
  }
  static constexpr double a = 1e-4;  ///< the stiffness' factor in M + a K + b D
  static constexpr double b = 1e-2;
  Body body;
  std::size_t n = 0;
  std::vector<char> constrained;
  std::vector<Vec3> rhs;
};

/// The system's solution hidden in a combination with noise, for the Galerkin start: `exact`
/// (CG from zero to 1e-12, its stats in `cold`), a noise field and exact + 0.3 noise.
struct HiddenSolution {
  LinearSolveStats cold;
  std::vector<Vec3> exact;
  std::vector<Vec3> noise;
  std::vector<Vec3> mixed;
};

HiddenSolution hide_solution(ShearedSystem& system) {
  LinearSolverOptions options;
  options.tolerance = 1e-12;
  options.warm_start = false;
  HiddenSolution hidden;
  hidden.exact.assign(system.n, Vec3::Zero());
  hidden.cold = LinearizedSystemSolver(options).solve(system.body.system, 1.0, system.a, system.b,
                                                      system.constrained, system.rhs, hidden.exact);
  hidden.noise = random_field(system.n, 1.0, 8);
  hidden.mixed.resize(system.n);
  for (std::size_t i = 0; i < system.n; ++i) {
    hidden.mixed[i] = hidden.exact[i] + 0.3 * hidden.noise[i];
  }
  return hidden;
}

/// |rhs - (M + a K + b D) x| / |rhs| over the free rows, from the model's own products in
/// double: the residual a solve must report, found without the solver.
double true_relative_residual(ShearedSystem& system, std::span<const Vec3> x) {
  const std::size_t n = x.size();
  const auto masses = system.body.system.masses();
  std::vector<Vec3> product(n);
  for (std::size_t i = 0; i < n; ++i) {
    product[i] = masses[i] * x[i];
  }
  system.body.system.add_linearized_product(system.a, system.b, x, product);
  double residual = 0.0;
  double rhs_norm = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (system.constrained[i] == 0) {
      residual += (system.rhs[i] - product[i]).squaredNorm();
      rhs_norm += system.rhs[i].squaredNorm();
    }
  }
  return std::sqrt(residual / rhs_norm);
}

TEST(FemSolver, GalerkinStartFromABasisThatSpansTheSolutionNeedsNoIterations) {
  ShearedSystem system;
  const std::size_t n = system.n;
  const HiddenSolution hidden = hide_solution(system);
  ASSERT_LE(hidden.cold.relative_residual, 1e-12);
  ASSERT_GT(hidden.cold.iterations, 10);
  const std::vector<Vec3>& exact = hidden.exact;
  // The solution hidden in a combination with noise, plus a repeated (dependent) field.
  const std::vector<std::span<const Vec3>> basis = {hidden.noise, hidden.mixed, hidden.noise};
  LinearSolverOptions options;
  options.warm_start = false;
  options.tolerance = 1e-8;
  LinearizedSystemSolver started(options);
  std::vector<Vec3> x_started(n, Vec3::Constant(1.0));  // ignored: the basis decides
  const LinearSolveStats stats = started.solve(system.body.system, 1.0, system.a, system.b,
                                               system.constrained, system.rhs, x_started, basis);
  EXPECT_EQ(stats.iterations, 0);
  EXPECT_LE(stats.relative_residual, 1e-8);
  EXPECT_LT(max_difference(x_started, exact), 1e-7 * max_norm(exact));
  // A basis of noise alone starts no worse than zero in the energy norm, and CG still
  // reaches the tolerance.
  const std::vector<std::span<const Vec3>> unrelated = {hidden.noise};
  std::vector<Vec3> x_noise(n, Vec3::Zero());
  const LinearSolveStats noisy = started.solve(system.body.system, 1.0, system.a, system.b,
                                               system.constrained, system.rhs, x_noise, unrelated);
  EXPECT_LE(noisy.relative_residual, 1e-8);
  EXPECT_LT(max_difference(x_noise, exact), 1e-5 * max_norm(exact));
}

TEST(FemSolver, ProductsOfSeveralVectorsAtOnceMatchOneByOne) {
  // The Galerkin start multiplies its basis in one pass over the matrix, every vector over a
  // chunk of rows while its blocks are in cache, through the same row kernel as one product:
  // the same numbers.
  Body body(box({4, 4, 4}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0));
  const std::size_t n = body.mesh.vertex_count();
  linearize_sheared(body);
  BlockSparseMatrix matrix;
  ASSERT_TRUE(body.system.assemble_linearization(1e-4, 1e-2, matrix));
  std::vector<std::vector<Vec3>> fields;
  std::vector<std::vector<Vec3>> together(5, std::vector<Vec3>(n));
  std::vector<std::span<const Vec3>> inputs;
  std::vector<std::span<Vec3>> outputs;
  for (unsigned m = 0; m < 5; ++m) {
    fields.push_back(random_field(n, 1.0, 40 + m));
  }
  for (std::size_t m = 0; m < 5; ++m) {
    inputs.emplace_back(fields[m]);
    outputs.emplace_back(together[m]);
  }
  matrix.multiply_several(inputs, outputs);
  for (std::size_t m = 0; m < 5; ++m) {
    std::vector<Vec3> alone(n);
    matrix.multiply(fields[m], alone);
    EXPECT_EQ(max_difference(alone, together[m]), 0.0) << "vector " << m;
  }
  // From the float copy: the same numbers as one vector at a time, whatever the chunks.
  matrix.refresh_single_precision();
  matrix.multiply_several_single(inputs, outputs);
  for (std::size_t m = 0; m < 5; ++m) {
    std::vector<Vec3> alone(n);
    matrix.multiply_rows_single(0, n, fields[m], alone.data());
    EXPECT_EQ(max_difference(alone, together[m]), 0.0) << "vector " << m;
  }
}

TEST(FemSolver, RowsACutMovesAndAddsLeaveTheMatricesWhereTheyAreUntilTwiceAsManyBlocks) {
  // A cut moves every row it edits to the end of the shared storage and adds rows and blocks.
  // A matrix that outgrew its capacity was copied into fresh pages within the cutting frame,
  // a hitch of 20-60x the frame's usual update on the 50k body (BENCHMARKS.md). Here a cut's
  // edits, repeated until the blocks have doubled, as the per-element arrays may: a new vertex
  // coupled to four rows a step, each edited row moved.
  Body body(box({8, 8, 8}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0));
  BlockSparseMatrix stiffness;
  stiffness.build_pattern(body.mesh);
  BlockSparseMatrix system;
  system.match_pattern(stiffness);
  system.refresh_single_precision();
  const std::size_t blocks = stiffness.block_count();
  const Mat3* stiffness_values = stiffness.values().data();
  const Mat3* system_values = system.values().data();
  std::mt19937 random(5);
  int packed = 0;
  while (stiffness.block_count() + 16 < 2 * blocks) {
    const auto vertex = static_cast<VertexId>(stiffness.rows());
    stiffness.add_rows(stiffness.rows() + 1);
    std::vector<VertexId> coupled{vertex};
    for (int k = 0; k < 4; ++k) {
      const auto row = static_cast<VertexId>(random() % vertex);
      std::vector<VertexId> columns(stiffness.row_columns(row).begin(),
                                    stiffness.row_columns(row).end());
      columns.push_back(vertex);  // the largest: still sorted
      stiffness.edit_row(row, columns);
      coupled.push_back(row);
    }
    std::sort(coupled.begin(), coupled.end());
    coupled.erase(std::unique(coupled.begin(), coupled.end()), coupled.end());
    stiffness.edit_row(vertex, coupled);
    packed += stiffness.compact_if_fragmented() ? 1 : 0;
    system.match_pattern(stiffness);
    system.refresh_single_precision();
    ASSERT_EQ(stiffness.values().data(), stiffness_values)
        << "copied at " << stiffness.block_count() << " blocks of " << blocks;
    ASSERT_EQ(system.values().data(), system_values)
        << "copied at " << system.block_count() << " blocks of " << blocks;
  }
  EXPECT_GT(packed, 0) << "the storage was never packed: the test did not reach that far";
}

TEST(FemSolver, AFloatGalerkinStartStopsOnTheTrueResidual) {
  // At a real-time tolerance the start's products are in single precision and CG's first
  // residual is combined from them: within float rounding of the true one. A start that
  // meets the tolerance on that estimate is confirmed in double, so the solve reports the
  // true residual, never the estimate.
  ShearedSystem system;
  const std::size_t n = system.n;
  const HiddenSolution hidden = hide_solution(system);
  ASSERT_LE(hidden.cold.relative_residual, 1e-12);
  const std::vector<std::span<const Vec3>> basis = {hidden.noise, hidden.mixed};
  LinearSolverOptions options;
  options.warm_start = false;
  for (const double tolerance : {1e-3, 1e-5}) {
    options.tolerance = tolerance;
    LinearizedSystemSolver solver(options);
    std::vector<Vec3> x(n, Vec3::Zero());
    const LinearSolveStats stats = solver.solve(system.body.system, 1.0, system.a, system.b,
                                                system.constrained, system.rhs, x, basis);
    const double truth = true_relative_residual(system, x);
    EXPECT_EQ(stats.iterations, 0) << tolerance;
    EXPECT_LE(stats.relative_residual, tolerance);
    EXPECT_GT(truth, 0.0);
    EXPECT_NEAR(stats.relative_residual, truth, 1e-6 * truth) << tolerance;
    // Float's rounding: the start is within about 1e-7 of the solution, not exact.
    EXPECT_LT(max_difference(x, hidden.exact), 1e-5 * max_norm(hidden.exact));
  }
}

TEST(FemSolver, SinglePrecisionProductsStopOnTheTrueResidual) {
  // CG multiplies by a float copy of the matrix; the copy's products agree with the double
  // ones to float rounding, and a tolerance far below what float alone can reach (1e-12) is
  // still met on the residual formed in double, by restarting from it.
  ShearedSystem system;
  const std::size_t n = system.n;
  BlockSparseMatrix matrix;
  ASSERT_TRUE(system.body.system.assemble_linearization(system.a, system.b, matrix));
  matrix.refresh_single_precision();
  const std::vector<Vec3> p = random_field(n, 1.0, 3);
  std::vector<Vec3> in_double(n);
  std::vector<Vec3> in_single(n);
  matrix.multiply_rows(0, n, p, in_double.data());
  matrix.multiply_rows_single(0, n, p, in_single.data());
  double largest_block = 0.0;
  for (const Mat3& block : matrix.values()) {
    largest_block = std::max(largest_block, block.cwiseAbs().maxCoeff());
  }
  const double rows_bound = 27.0 * 3.0 * largest_block * max_norm(p) * 0x1p-24;
  EXPECT_LE(max_difference(in_double, in_single), rows_bound);
  EXPECT_GT(max_difference(in_double, in_single), 0.0);  // the copy is float, not the same

  auto solve = [&](bool single, std::vector<Vec3>& solution) {
    LinearSolverOptions options;
    options.tolerance = 1e-12;
    options.warm_start = false;
    options.single_precision_products = single;
    LinearizedSystemSolver solver(options);
    solution.assign(n, Vec3::Zero());
    return solver.solve(system.body.system, 1.0, system.a, system.b, system.constrained, system.rhs,
                        solution);
  };
  std::vector<Vec3> solution_double;
  std::vector<Vec3> solution_single;
  const LinearSolveStats double_stats = solve(false, solution_double);
  const LinearSolveStats single_stats = solve(true, solution_single);
  EXPECT_EQ(double_stats.refinements, 0);
  EXPECT_GE(single_stats.refinements, 1);
  // The residual of the single-precision run, formed here from the model's own products.
  EXPECT_LE(single_stats.relative_residual, 1e-12);
  EXPECT_LE(true_relative_residual(system, solution_single), 2e-12);
  EXPECT_LT(max_difference(solution_single, solution_double), 1e-9 * max_norm(solution_double));
}

TEST(FemSolver, ANotANumberInTheStartEndsTheSolve) {
  // A diverged step leaves NaN in the solution CG starts from: the solve must return with a
  // residual that says so (the engine's divergence check reports it), not restart forever.
  Body body(box({3, 3, 3}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0));
  body.conditions.fix(at_plane(body.mesh, 2, 0.0));
  const std::size_t n = body.mesh.vertex_count();
  const auto rest = body.state.x.values();
  body.system.prepare_linearization(0.0, std::vector<Vec3>(rest.begin(), rest.end()),
                                    std::vector<Vec3>(n, Vec3::Zero()));
  const std::vector<char> constrained = held_rows(body);
  const std::vector<Vec3> rhs = random_field(n, 1e-3, 5);
  for (const bool single : {true, false}) {
    LinearSolverOptions options;
    options.tolerance = 1e-8;
    options.single_precision_products = single;
    LinearizedSystemSolver solver(options);
    std::vector<Vec3> solution = random_field(n, 1e-3, 6);
    solution[n - 1].x() = std::numeric_limits<double>::quiet_NaN();  // a free vertex: top corner
    const LinearSolveStats stats =
        solver.solve(body.system, 1.0, 1e-4, 1e-2, constrained, rhs, solution);
    EXPECT_FALSE(std::isfinite(stats.relative_residual)) << "single " << single;
  }
}

TEST(FemSolver, StartingFromEarlierSolutionsKeepsTheTrajectoryAndSavesIterations) {
  // The peers' box (n = 6) for 40 steps, CG to 1e-9: starting each step from the Galerkin
  // combination of the last eight solutions, from the extrapolation of the last two, and
  // from zero follow one trajectory; the history needs the fewest iterations.
  auto run = [](int history, bool warm, std::size_t& iterations) {
    Body body(box({6, 6, 6}, Vec3(0.1, 0.1, 0.1)), material(3e3, 0.45, 1000.0));
    body.conditions.fix(at_plane(body.mesh, 2, 0.0));
    body.conditions.set_gravity(Vec3(0.0, 0.0, -9.81));
    BackwardEulerOptions options;
    options.solver.tolerance = 1e-9;
    options.solver.start_history = history;
    options.solver.warm_start = warm;
    BackwardEuler integrator(options);
    iterations = 0;
    for (int s = 0; s < 40; ++s) {
      integrator.step(body.system, body.state.x.values(), body.state.v.values(), s * 0.01, 0.01);
      iterations += integrator.stats().solver_iterations_last_step;
    }
    const auto positions = body.state.x.values();
    return std::vector<Vec3>(positions.begin(), positions.end());
  };
  std::size_t with_history = 0;
  std::size_t extrapolated = 0;
  std::size_t cold = 0;
  const std::vector<Vec3> a = run(8, true, with_history);
  const std::vector<Vec3> b = run(0, true, extrapolated);
  const std::vector<Vec3> c = run(0, false, cold);
  std::printf("CG iterations over 40 steps: history %zu, extrapolated %zu, from zero %zu\n",
              with_history, extrapolated, cold);
  EXPECT_LT(max_difference(a, c), 1e-7);  // m, against a sag of about 1 cm
  EXPECT_LT(max_difference(b, c), 1e-7);
  EXPECT_LT(with_history, extrapolated);
  EXPECT_LT(extrapolated, cold);
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(MaterialFraction, LivesOnTheMeshFollowsSplitsAndBothModelsWeighIt) {
  // A cutter that keeps elements whole (XFEM) sets the fraction on the mesh; each model weighs
  // its elements' mass and stiffness by it, and children of a split keep their parent's.
  BoxGridOptions options;
  options.cells = {2, 2, 2};
  options.size = Vec3(0.02, 0.02, 0.02);
  TetMesh mesh = make_box_grid(options);
  const Material material = material_preset("liver");
  CorotationalFemModel fem(mesh, material);
  MassSpringModel springs(mesh, material, MassSpringParameters{});
  const double full = material.density * 0.02 * 0.02 * 0.02;  // kg
  EXPECT_NEAR(fem.total_mass(), full, 1e-12 * full);
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    mesh.set_material_fraction(static_cast<TetId>(t), t < 24 ? 0.25 : 1.0);
  }
  const double weighed = full * (24 * 0.25 + 24 * 1.0) / 48.0;
  EXPECT_NEAR(fem.total_mass(), weighed, 1e-12 * full);
  EXPECT_NEAR(springs.total_mass(), weighed, 1e-12 * full);
  const TetId first = 0;
  (void)split_edge(mesh, mesh.tet_edges(first)[0], 0.3);
  fem.refresh();
  springs.refresh();
  EXPECT_NEAR(fem.total_mass(), weighed, 1e-12 * full);
  EXPECT_NEAR(springs.total_mass(), weighed, 1e-12 * full);
  double lumped = 0.0;
  for (double m : springs.masses()) {
    lumped += m;
  }
  EXPECT_NEAR(lumped, weighed, 1e-12 * full);
  EXPECT_THROW(mesh.set_material_fraction(0, -0.1), InputError);
}

}  // namespace
}  // namespace incise
