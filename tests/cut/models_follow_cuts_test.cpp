// Models follow cuts locally (the issue "An engine you can step and cut at any size"): after
// every move of the blade, a model that updated only what the move touched equals, bit for
// bit, the same model built afresh from the cut mesh (as a resumed run builds it), on real
// meshes and perturbed grids cut along random walks; and a move marks only the vertices near
// the blade, not the body.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string_view>

#include "../blade_walks.hpp"
#include "incise/core/state_archive.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/physics/block_sparse.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mass_spring.hpp"

namespace incise {
namespace {

using test::bounds;
using test::random_walk;
using test::walk_mesh;

Material tissue() {
  Material m;
  m.young_modulus = 3e3;
  m.poisson_ratio = 0.45;
  m.density = 1000.0;
  return m;
}

/// A deformed state that new vertices get too: a smooth field of the rest position (m), a
/// different one for each `phase` (so nothing left from an earlier evaluation can pass).
std::vector<Vec3> deformed(const TetMesh& mesh, double phase = 0.0) {
  std::vector<Vec3> x(mesh.vertex_count());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const Vec3& p = mesh.rest_position(static_cast<VertexId>(i));
    x[i] = p + 0.002 * Vec3(std::sin(300.0 * p.y() + phase), std::cos(200.0 * p.z()),
                            std::sin(250.0 * p.x() - phase));
  }
  return x;
}

std::vector<Vec3> velocities(const TetMesh& mesh) {
  std::vector<Vec3> v(mesh.vertex_count());
  for (std::size_t i = 0; i < v.size(); ++i) {
    const Vec3& p = mesh.rest_position(static_cast<VertexId>(i));
    v[i] = Vec3(std::cos(100.0 * p.x()), 0.5, std::sin(150.0 * p.y()));
  }
  return v;
}

/// What a model gives a solver: masses, forces, the linearised product, and the assembled
/// matrix row by row (columns and blocks).
struct ModelOutput {
  std::vector<double> masses;
  double frequency = 0.0;  ///< the bound explicit schemes ask for (1/s)
  std::vector<Vec3> forces;
  std::vector<Vec3> product;
  std::vector<Vec3> vertex_forces;  ///< one vertex at a time (explicit traversals)
  std::vector<std::vector<VertexId>> neighbours;
  std::vector<std::vector<VertexId>> columns;
  std::vector<std::vector<Mat3>> blocks;
};

ModelOutput output_of(ForceModel& model, ForceLinearization& linearization, const TetMesh& mesh,
                      double phase = 0.0) {
  model.refresh();
  ModelOutput out;
  out.masses.assign(model.masses().begin(), model.masses().end());
  out.frequency = model.max_vertex_frequency();
  const std::vector<Vec3> x = deformed(mesh, phase);
  const std::vector<Vec3> v = velocities(mesh);
  out.forces.assign(mesh.vertex_count(), Vec3::Zero());
  model.add_forces(x, v, out.forces);
  if (const VertexForces* per_vertex = model.vertex_forces(); per_vertex != nullptr) {
    const NeighborState state = [&](VertexId j, Vec3& xj, Vec3& vj) {
      xj = x[static_cast<std::size_t>(j)];
      vj = v[static_cast<std::size_t>(j)];
    };
    for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
      const auto vertex = static_cast<VertexId>(i);
      out.vertex_forces.push_back(per_vertex->vertex_force(vertex, x[i], v[i], state));
      const auto around = per_vertex->neighbors(vertex);
      out.neighbours.emplace_back(around.begin(), around.end());
    }
  }
  linearization.prepare_linearization(x, v);
  out.product.assign(mesh.vertex_count(), Vec3::Zero());
  linearization.add_linearized_product(1.0, 0.01, v, out.product);
  BlockSparseMatrix matrix;
  if (linearization.assemble_linearization(1.0, 0.01, matrix)) {
    for (std::size_t i = 0; i < matrix.rows(); ++i) {
      const auto row = matrix.row_columns(static_cast<VertexId>(i));
      out.columns.emplace_back(row.begin(), row.end());
      out.blocks.emplace_back();
      for (VertexId column : row) {
        out.blocks.back().push_back(matrix.values()[matrix.find(static_cast<VertexId>(i), column)]);
      }
    }
  }
  return out;
}

/// The model as it followed the edits. Evaluated twice: rotations start from the last ones
/// found (a warm start that moves the last bits), so both models start from this state's.
ModelOutput followed_output_of(ForceModel& model, ForceLinearization& linearization,
                               const TetMesh& mesh, double phase) {
  (void)output_of(model, linearization, mesh, phase);
  return output_of(model, linearization, mesh, phase);
}

/// The model after a restore: everything built again from the mesh and its attributes.
template <typename Model>
ModelOutput rebuilt_output_of(Model& model, const TetMesh& mesh, double phase = 0.0) {
  StateReader nothing(std::string_view{}, "no checkpoint");
  model.load_state(nothing);
  return output_of(model, model, mesh, phase);
}

void expect_same(const ModelOutput& followed, const ModelOutput& rebuilt,
                 const std::string& where) {
  ASSERT_EQ(followed.masses.size(), rebuilt.masses.size()) << where;
  ASSERT_EQ(followed.frequency, rebuilt.frequency) << where;
  for (std::size_t i = 0; i < followed.masses.size(); ++i) {
    ASSERT_EQ(followed.masses[i], rebuilt.masses[i]) << where << ", mass of vertex " << i;
    ASSERT_EQ(followed.forces[i], rebuilt.forces[i]) << where << ", force on vertex " << i;
    ASSERT_EQ(followed.product[i], rebuilt.product[i]) << where << ", product at vertex " << i;
  }
  ASSERT_EQ(followed.vertex_forces, rebuilt.vertex_forces) << where;
  ASSERT_EQ(followed.neighbours, rebuilt.neighbours) << where;
  ASSERT_EQ(followed.columns, rebuilt.columns) << where;
  for (std::size_t i = 0; i < followed.blocks.size(); ++i) {
    for (std::size_t k = 0; k < followed.blocks[i].size(); ++k) {
      ASSERT_EQ(followed.blocks[i][k], rebuilt.blocks[i][k]) << where << ", row " << i;
    }
  }
}

template <typename MakeModel>
void check_followed_equals_rebuilt(const MakeModel& make_model) {
  const bool have_data = std::filesystem::exists(test::data_dir());
  for (unsigned seed = 1; seed <= test::seed_count(6); ++seed) {
    std::mt19937 rng(4100 + seed);
    TetMesh mesh = walk_mesh(seed, have_data, rng);
    auto model = make_model(mesh);
    (void)output_of(*model, *model, mesh);
    SubdivisionCutter cutter(mesh);
    const std::vector<BladePose> path = random_walk(bounds(mesh), rng, 30);
    test::play(cutter, path, [&](std::size_t pose) {
      if (pose % 6 != 0 && pose + 1 != path.size()) {
        return;
      }
      const std::string where = "seed " + std::to_string(seed) + ", pose " + std::to_string(pose);
      const auto phase = static_cast<double>(pose);
      const ModelOutput followed = followed_output_of(*model, *model, mesh, phase);
      const ModelOutput rebuilt = rebuilt_output_of(*model, mesh, phase);
      expect_same(followed, rebuilt, where);
    });
    ASSERT_GT(mesh.tet_count(), 0u);
  }
}

TEST(ModelsFollowCuts, CorotationalFemUpdatedLocallyEqualsOneBuiltAfresh) {
  check_followed_equals_rebuilt([](TetMesh& mesh) {
    CorotationalFemParameters parameters;
    parameters.rayleigh_stiffness = 0.01;
    return std::make_unique<CorotationalFemModel>(mesh, tissue(), parameters);
  });
}

/// Random edits of every kind the mesh has (splits of edges, faces and tetrahedra, removals
/// that move the last tetrahedron to another id, vertices duplicated and collapsed back),
/// each compared with a model built afresh.
template <typename MakeModel>
void check_random_edits(const MakeModel& make_model) {
  std::mt19937 rng(91);
  TetMesh mesh = test::perturbed_grid(rng);
  auto model = make_model(mesh);
  (void)output_of(*model, *model, mesh);
  std::uniform_real_distribution<double> weight(0.2, 0.8);
  for (int edit = 0; edit < 60; ++edit) {
    const auto tet = static_cast<TetId>(rng() % mesh.tet_count());
    switch (edit % 5) {
      case 0:
        (void)split_tet(mesh, tet, {0.25, 0.25, 0.25, 0.25});
        break;
      case 1:
        (void)split_edge(mesh, static_cast<EdgeId>(rng() % mesh.edge_count()), weight(rng));
        break;
      case 2:
        (void)split_face(mesh, tet, static_cast<int>(rng() % 4), {0.3, 0.3, 0.4});
        break;
      case 3:
        mesh.remove_tet(tet);  // the last tetrahedron takes its id
        break;
      default: {
        const VertexId vertex = mesh.tet(tet)[rng() % 4];
        const std::vector<TetId> one{tet};
        (void)mesh.duplicate_vertex(vertex, one);
        break;
      }
    }
    const std::string where = "edit " + std::to_string(edit);
    const ModelOutput followed = followed_output_of(*model, *model, mesh, edit);
    const ModelOutput rebuilt = rebuilt_output_of(*model, mesh, edit);
    expect_same(followed, rebuilt, where);
  }
}

TEST(ModelsFollowCuts, CorotationalFemFollowsEveryKindOfEdit) {
  check_random_edits(
      [](TetMesh& mesh) { return std::make_unique<CorotationalFemModel>(mesh, tissue()); });
}

std::unique_ptr<MassSpringModel> mass_spring(TetMesh& mesh) {
  MassSpringParameters parameters;
  parameters.spring_damping_ratio = 0.1;
  return std::make_unique<MassSpringModel>(mesh, tissue(), parameters);
}

TEST(ModelsFollowCuts, MassSpringUpdatedLocallyEqualsOneBuiltAfresh) {
  check_followed_equals_rebuilt(mass_spring);
}

TEST(ModelsFollowCuts, MassSpringFollowsEveryKindOfEdit) {
  check_random_edits(mass_spring);
}

TEST(ModelsFollowCuts, MatrixFreeFemProductsMatchTheAssembledOnesAfterCuts) {
  const bool have_data = std::filesystem::exists(test::data_dir());
  std::mt19937 rng(77);
  TetMesh mesh = walk_mesh(3, have_data, rng);
  CorotationalFemModel model(mesh, tissue());
  SubdivisionCutter cutter(mesh);
  test::play(cutter, random_walk(bounds(mesh), rng, 20), [](std::size_t) {});
  model.refresh();
  const std::vector<Vec3> x = deformed(mesh);
  const std::vector<Vec3> v = velocities(mesh);
  std::vector<Vec3> assembled(mesh.vertex_count(), Vec3::Zero());
  std::vector<Vec3> matrix_free(mesh.vertex_count(), Vec3::Zero());
  std::vector<Mat3> diagonal_assembled(mesh.vertex_count(), Mat3::Zero());
  std::vector<Mat3> diagonal_free(mesh.vertex_count(), Mat3::Zero());
  model.set_assemble(true);
  model.prepare_linearization(x, v);
  model.add_linearized_product(1.0, 0.0, v, assembled);
  model.add_linearized_diagonal(1.0, 0.0, diagonal_assembled);
  model.set_assemble(false);
  model.prepare_linearization(x, v);
  model.add_linearized_product(1.0, 0.0, v, matrix_free);
  model.add_linearized_diagonal(1.0, 0.0, diagonal_free);
  double scale = 0.0;
  for (const Vec3& y : assembled) {
    scale = std::max(scale, y.norm());
  }
  ASSERT_GT(scale, 0.0);
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    EXPECT_LT((assembled[i] - matrix_free[i]).norm(), 1e-12 * scale) << "vertex " << i;
    EXPECT_LT((diagonal_assembled[i] - diagonal_free[i]).norm(),
              1e-12 * (1.0 + diagonal_assembled[i].norm()))
        << "vertex " << i;
  }
}

/// The most vertices one 1 mm move of a vertical blade marked, cutting 3 cm into a box of
/// n x n x 6 cells of 1 cm (the same blade, the same cells, whatever n); and the vertex count
/// before the cut.
std::pair<std::size_t, std::size_t> worst_marked(int n) {
  BoxGridOptions grid;
  grid.cells = {n, n, 6};
  grid.size = Vec3(0.01 * n, 0.01 * n, 0.06);
  TetMesh mesh = make_box_grid(grid);
  CorotationalFemModel model(mesh, tissue());
  SubdivisionCutter cutter(mesh);
  const double x = 0.01 * (n / 2) + 0.0037;  // m, across a column of cells
  BladePose pose{0.0, Vec3(x, -0.005, -0.01), Vec3(x, -0.005, 0.07)};
  cutter.start(pose);
  std::size_t worst = 0;
  const std::size_t tets = mesh.tet_count();
  const std::size_t vertices = mesh.vertex_count();
  for (int move = 1; move <= 35; ++move) {
    pose.tip.y() = pose.base.y() = -0.005 + 0.001 * move;
    pose.time = 0.01 * move;
    cutter.move_to(pose);
    worst = std::max(worst, model.pending_vertices());
    model.refresh();
    EXPECT_EQ(model.pending_vertices(), 0u);
  }
  EXPECT_GT(mesh.tet_count(), tets) << "the blade cut nothing";
  return {worst, vertices};
}

TEST(ModelsFollowCuts, AMoveMarksWhatTheBladeMetNotTheBody) {
  const auto [small_worst, small_vertices] = worst_marked(6);
  const auto [large_worst, large_vertices] = worst_marked(18);
  EXPECT_GT(large_vertices, 6 * small_vertices);
  EXPECT_GT(small_worst, 0u);
  // The same cut marks the same vertices whatever the body around it.
  EXPECT_EQ(large_worst, small_worst) << "of " << small_vertices << " and " << large_vertices;
}

}  // namespace
}  // namespace incise
