// The mass-spring model: masses, springs and boundary conditions follow every mesh edit;
// all integrators agree on the static equilibrium; the hierarchical scheme stays local.

#include "incise/physics/mass_spring.hpp"

#include <gtest/gtest.h>

#include <random>

#include "incise/core/error.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"

namespace incise {
namespace {

TetMesh block(std::array<int, 3> cells, const Vec3& size) {
  BoxGridOptions options;
  options.cells = cells;
  options.size = size;
  return make_box_grid(options);
}

TEST(Materials, PresetsAndChecks) {
  const Material liver = material_preset("liver");
  EXPECT_NEAR(liver.shear_modulus(), 1.8e3, 1e-9);
  EXPECT_NEAR(liver.young_modulus, 5.29e3, 10.0);
  EXPECT_EQ(liver.density, 1060.0);
  for (const std::string& name : material_preset_names()) {
    EXPECT_NO_THROW(material_preset(name).check());
  }
  try {
    (void)material_preset("livr");
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("liver"), std::string::npos);
  }
  Material bad = liver;
  bad.poisson_ratio = 0.5;
  EXPECT_THROW(bad.check(), InputError);
}

TEST(MassSpring, MassAndStiffnessFromTheMaterial) {
  TetMesh mesh = block({2, 2, 2}, Vec3(0.02, 0.02, 0.02));
  const Material liver = material_preset("liver");
  MassSpringModel model(mesh, liver, {});
  EXPECT_NEAR(model.total_mass(), liver.density * 8e-6, 1e-15);
  double lumped = 0.0;
  for (double m : model.masses()) {
    lumped += m;
  }
  EXPECT_NEAR(lumped, model.total_mass(), 1e-15);
  // van Gelder: k = E * (volume of the tets around the edge) / length^2.
  const EdgeId edge = mesh.find_edge(mesh.tet(0)[0], mesh.tet(0)[1]);
  double volume = 0.0;
  for (TetId t : mesh.edge_tets(edge)) {
    volume += signed_volume(mesh, t);
  }
  const auto ends = mesh.edge(edge);
  const double length = (mesh.rest_position(ends[0]) - mesh.rest_position(ends[1])).norm();
  EXPECT_NEAR(model.spring(edge).stiffness, liver.young_modulus * volume / (length * length), 1e-9);
  EXPECT_NEAR(model.spring(edge).rest_length, length, 1e-15);
}

/// Every spring and mass of `model` equals those of a model built afresh on the same mesh.
void expect_matches_fresh_model(TetMesh& mesh, const MassSpringModel& model, double prestrain) {
  TetMesh copy = mesh;
  MassSpringModel fresh(copy, model.material(), {0.1, prestrain});
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    ASSERT_NEAR(model.masses()[v], fresh.masses()[v], 1e-12 * fresh.masses()[v] + 1e-18)
        << "vertex " << v;
  }
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const Spring& mine = model.spring(static_cast<EdgeId>(e));
    const Spring& theirs = fresh.spring(static_cast<EdgeId>(e));
    ASSERT_NEAR(mine.stiffness, theirs.stiffness, 1e-9 * theirs.stiffness) << "edge " << e;
    ASSERT_NEAR(mine.rest_length, theirs.rest_length, 1e-15) << "edge " << e;
    ASSERT_NEAR(mine.damping, theirs.damping, 1e-9 * theirs.damping + 1e-15) << "edge " << e;
  }
}

TEST(MassSpring, FollowsEditsAndConservesMass) {
  TetMesh mesh = block({3, 2, 2}, Vec3(0.03, 0.02, 0.02));
  const double prestrain = 0.1;
  MassSpringModel model(mesh, material_preset("liver"), {0.1, prestrain});
  const double total = model.total_mass();
  std::mt19937 rng(5);
  for (int step = 0; step < 200; ++step) {
    const auto t = static_cast<TetId>(rng() % mesh.tet_count());
    switch (rng() % 4) {
      case 0:
        (void)split_edge(mesh, mesh.tet_edges(t)[rng() % 6], 0.3);
        break;
      case 1:
        (void)split_face(mesh, t, static_cast<int>(rng() % 4), {0.2, 0.3, 0.5});
        break;
      case 2:
        (void)split_tet(mesh, t, {0.1, 0.2, 0.3, 0.4});
        break;
      default: {
        // Open a crack at a vertex: some of its tetrahedra move to a copy.
        const VertexId vertex = mesh.tet(t)[rng() % 4];
        const std::array<TetId, 1> moved{t};
        (void)mesh.duplicate_vertex(vertex, moved);
      }
    }
    model.refresh();
    double lumped = 0.0;
    for (double m : model.masses()) {
      lumped += m;
    }
    ASSERT_NEAR(lumped, total, 1e-12 * total) << "after edit " << step;
    ASSERT_EQ(model.masses().size(), mesh.vertex_count());
  }
  expect_matches_fresh_model(mesh, model, prestrain);
}

TEST(BoundaryConditions, FollowEdits) {
  TetMesh mesh = block({2, 2, 2}, Vec3(1, 1, 1));
  BoundaryConditions conditions(mesh);
  const auto bottom = vertices_in_box(mesh, Vec3(-1, -1, -1e-9), Vec3(2, 2, 1e-9));
  ASSERT_EQ(bottom.size(), 9u);
  conditions.fix(bottom);
  EXPECT_EQ(conditions.constrained_count(), 9u);
  // A vertex on a bottom edge is fixed; one on an edge leaving the bottom is not.
  EdgeId along = kInvalidId;
  EdgeId leaving = kInvalidId;
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& [a, b] = mesh.edge(static_cast<EdgeId>(e));
    const bool a_fixed = conditions.is_constrained(a);
    const bool b_fixed = conditions.is_constrained(b);
    if (a_fixed && b_fixed) {
      along = static_cast<EdgeId>(e);
    } else if (a_fixed != b_fixed) {
      leaving = static_cast<EdgeId>(e);
    }
  }
  ASSERT_NE(along, kInvalidId);
  ASSERT_NE(leaving, kInvalidId);
  const VertexId leaving_vertex = split_edge(mesh, leaving, 0.5);
  const VertexId along_vertex = split_edge(mesh, along, 0.5);
  EXPECT_TRUE(conditions.is_constrained(along_vertex));
  EXPECT_FALSE(conditions.is_constrained(leaving_vertex));
  // A duplicate keeps its original's constraint and does not double point loads.
  conditions.add_force(std::array<VertexId, 1>{bottom[0]}, Vec3(0, 0, 1));
  const std::vector<TetId> around(mesh.vertex_tets(bottom[0]).begin(),
                                  mesh.vertex_tets(bottom[0]).end());
  const VertexId copy = mesh.duplicate_vertex(bottom[0], std::span<const TetId>(around).first(1));
  EXPECT_TRUE(conditions.is_constrained(copy));
  EXPECT_TRUE(conditions.point_force(copy).isZero());
  EXPECT_EQ(conditions.point_force(bottom[0]), Vec3(0, 0, 1));
}

/// A 2 x 2 x 4-cell liver block (2 x 2 x 4 cm) hanging from its top face under gravity.
struct HangingBlock {
  HangingBlock()
      : mesh(block({2, 2, 4}, Vec3(0.02, 0.02, 0.04))),
        model(mesh, material_preset("liver"), {0.2, 0.0}),
        conditions(mesh),
        system(mesh, model, conditions, {30.0, 0.0}),
        state(mesh) {
    conditions.fix(vertices_in_box(mesh, Vec3(-1, -1, 0.04 - 1e-9), Vec3(1, 1, 1)));
    conditions.set_gravity(Vec3(0, 0, -9.81));
  }
  /// Runs until the kinetic energy is negligible; returns the lowest z.
  double settle(Integrator& integrator, double dt, double duration) {
    const int steps = static_cast<int>(duration / dt);
    for (int s = 0; s < steps; ++s) {
      integrator.step(system, state.x.values(), state.v.values(), state.time, dt);
      state.time += dt;
    }
    EXPECT_LT(kinetic_energy(system.masses(), state.v.values()), 1e-16) << integrator.name();
    double lowest = 1.0;
    for (const Vec3& p : state.x.values()) {
      lowest = std::min(lowest, p.z());
    }
    return lowest;
  }
  TetMesh mesh;
  MassSpringModel model;
  BoundaryConditions conditions;
  MechanicalSystem system;
  SimulationState state;
};

TEST(Equilibrium, EveryIntegratorReachesTheSameSag) {
  // Reference: backward Euler with large steps, which converges to the static state.
  HangingBlock reference;
  BackwardEulerOptions options;
  options.solver.tolerance = 1e-12;
  BackwardEuler implicit(options);
  const double sag = -reference.settle(implicit, 0.01, 4.0);
  EXPECT_GT(sag, 1e-4);  // m: the block sags by a fraction of a millimetre to millimetres
  const double limit = explicit_stability_limit(reference.system, "symplectic-euler");

  auto check = [&](Integrator& integrator, double dt) {
    HangingBlock body;
    const double result = -body.settle(integrator, dt, 4.0);
    // Same equilibrium within 1e-6 of the sag (the schemes differ only on the way there).
    EXPECT_NEAR(result, sag, 1e-6 * sag) << integrator.name();
    double worst = 0.0;
    for (std::size_t i = 0; i < body.mesh.vertex_count(); ++i) {
      worst = std::max(worst, (body.state.x.values()[i] - reference.state.x.values()[i]).norm());
    }
    EXPECT_LT(worst, 1e-6 * sag) << integrator.name();
  };
  // Explicit Euler amplifies undamped modes at any step: it needs a step well inside the
  // damping of the highest modes (spring damping ratio 0.2 here).
  ExplicitEuler explicit_euler;
  check(explicit_euler, 0.1 * limit);
  SymplecticEuler symplectic;
  check(symplectic, 0.9 * limit);
  RungeKutta4 rk4;
  check(rk4, 0.9 * limit);
  HierarchicalRungeKutta4 hierarchical(HierarchicalOptions{4, 20});
  hierarchical.set_focus(0);  // depth 20 covers the whole block
  check(hierarchical, 2.0 * limit);
  HierarchicalRungeKutta4 full(HierarchicalOptions{2, 2});  // no focus: full relaxation
  check(full, limit);
}

TEST(Hierarchical, TouchesOnlyVerticesWithinTheDepthBound) {
  TetMesh mesh = block({8, 8, 8}, Vec3(0.08, 0.08, 0.08));
  MassSpringModel model(mesh, material_preset("liver"), {});
  BoundaryConditions conditions(mesh);
  conditions.set_gravity(Vec3(0, 0, -9.81));
  MechanicalSystem system(mesh, model, conditions);
  SimulationState state(mesh);
  const auto center = vertices_in_box(mesh, Vec3(0.04 - 1e-9, 0.04 - 1e-9, 0.04 - 1e-9),
                                      Vec3(0.04 + 1e-9, 0.04 + 1e-9, 0.04 + 1e-9));
  ASSERT_EQ(center.size(), 1u);
  // Independent count: breadth-first over mesh edges.
  std::vector<int> depth(mesh.vertex_count(), -1);
  std::vector<VertexId> queue{center[0]};
  depth[center[0]] = 0;
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const VertexId v = queue[head];
    for (TetId t : mesh.vertex_tets(v)) {
      for (VertexId w : mesh.tet(t)) {
        if (depth[w] < 0) {
          depth[w] = depth[v] + 1;
          queue.push_back(w);
        }
      }
    }
  }
  const int max_depth = 2;
  const auto within = static_cast<std::size_t>(
      std::count_if(depth.begin(), depth.end(), [&](int d) { return d >= 0 && d <= max_depth; }));
  HierarchicalRungeKutta4 integrator(HierarchicalOptions{8, max_depth});
  integrator.set_focus(center[0]);
  const std::vector<Vec3> before(state.x.values().begin(), state.x.values().end());
  const std::uint64_t updates_before = integrator.stats().vertex_updates;
  integrator.step(system, state.x.values(), state.v.values(), 0.0, 1e-4);
  EXPECT_EQ(integrator.stats().touched_last_step, within);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    const bool changed = state.x.values()[i] != before[i];
    moved += changed ? 1 : 0;
    if (depth[i] > max_depth) {
      EXPECT_FALSE(changed) << "vertex " << i << " at depth " << depth[i] << " moved";
    }
    EXPECT_EQ(integrator.last_depths()[i], depth[i] <= max_depth ? depth[i] : -1) << i;
  }
  EXPECT_EQ(moved, within);  // gravity moves every advanced vertex
  // Work: 8 sub-steps at the focus, 4 for each neighbour, 2 at depth 2.
  std::uint64_t expected = 0;
  for (int d : depth) {
    expected += d >= 0 && d <= max_depth
                    ? static_cast<std::uint64_t>(integrator.iterations_at_depth(d))
                    : 0;
  }
  EXPECT_EQ(integrator.stats().vertex_updates - updates_before, expected);
  EXPECT_LT(within, mesh.vertex_count() / 5);
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(MassSpringVolume, ForcesAreMinusTheEnergyGradientAndEveryPathGivesThemAlike) {
  // A perturbed block, squeezed: the volume term's forces are -dE/dx (central differences),
  // and the per-vertex path (the hierarchical schemes') gives the same force as add_forces.
  TetMesh mesh = make_box_grid({{2, 2, 2}, Vec3(0.02, 0.02, 0.02), Vec3::Zero(), 6});
  MassSpringParameters parameters;
  parameters.volume_stiffness = 1.0;
  parameters.spring_damping_ratio = 0.0;
  MassSpringModel model(mesh, material_preset("liver"), parameters);
  std::mt19937 random(3);
  std::uniform_real_distribution<double> jitter(-0.002, 0.002);
  std::vector<Vec3> x(mesh.rest_positions().begin(), mesh.rest_positions().end());
  for (Vec3& p : x) {
    p = Vec3(0.7 * p.x(), p.y(), p.z()) + Vec3(jitter(random), jitter(random), jitter(random));
  }
  const std::vector<Vec3> v(x.size(), Vec3::Zero());
  std::vector<Vec3> f(x.size(), Vec3::Zero());
  model.add_forces(x, v, f);
  const double h = 1e-7;
  for (std::size_t i = 0; i < x.size(); i += 3) {
    for (int k = 0; k < 3; ++k) {
      std::vector<Vec3> plus = x;
      std::vector<Vec3> minus = x;
      plus[i][k] += h;
      minus[i][k] -= h;
      const double gradient = (model.elastic_energy(plus) - model.elastic_energy(minus)) / (2 * h);
      EXPECT_NEAR(f[i][k], -gradient, 1e-6 * (1.0 + std::abs(gradient))) << "vertex " << i;
    }
    const Vec3 local = model.vertex_force(static_cast<VertexId>(i), x[i], v[i],
                                          [&](VertexId j, Vec3& xj, Vec3& vj) {
                                            xj = x[static_cast<std::size_t>(j)];
                                            vj = v[static_cast<std::size_t>(j)];
                                          });
    EXPECT_LT((local - f[i]).norm(), 1e-9 * (1.0 + f[i].norm())) << "vertex " << i;
  }
}

TEST(MassSpringVolume, ACornerPushedThroughItsFaceIsPushedBackWhereSpringsAloneAreIndifferent) {
  // One tetrahedron, its apex reflected through the opposite face: every edge keeps its
  // length, so the springs exert nothing, and the element is inside out. The volume term
  // pushes the apex back (springs only: no force at all).
  TetMesh mesh({Vec3(0, 0, 0), Vec3(0.01, 0, 0), Vec3(0, 0.01, 0), Vec3(0, 0, 0.01)},
               {Tet{0, 1, 2, 3}});
  std::vector<Vec3> x(mesh.rest_positions().begin(), mesh.rest_positions().end());
  x[3].z() = -0.01;
  const std::vector<Vec3> v(4, Vec3::Zero());
  for (const double stiffness : {0.0, 0.1}) {
    MassSpringParameters parameters;
    parameters.volume_stiffness = stiffness;
    MassSpringModel model(mesh, material_preset("liver"), parameters);
    std::vector<Vec3> f(4, Vec3::Zero());
    model.add_forces(x, v, f);
    if (stiffness == 0.0) {
      EXPECT_LT(f[3].norm(), 1e-12);
    } else {
      EXPECT_GT(f[3].z(), 0.0);  // back up through the face
    }
  }
}

}  // namespace
}  // namespace incise
