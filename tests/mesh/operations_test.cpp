// Conforming split operators: counts, volume, conformity, and refusals; the vertex collapse
// that undoes a face split once the face's edge is split.

#include "incise/mesh/operations.hpp"

#include <gtest/gtest.h>

#include "incise/core/error.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {
namespace {

TetMesh grid() {
  BoxGridOptions options;
  options.cells = {2, 2, 2};
  return make_box_grid(options);
}

TEST(Operations, SplitEdgeReplacesEveryTetAroundIt) {
  TetMesh mesh = grid();
  // The cube's centre vertex joins edges shared by several tetrahedra.
  const EdgeId edge = mesh.tet_edges(0)[0];
  const std::size_t around = mesh.edge_tets(edge).size();
  const std::size_t before = mesh.tet_count();
  const auto ends = mesh.edge(edge);
  const VertexId middle = split_edge(mesh, edge, 0.25);
  EXPECT_EQ(mesh.tet_count(), before + around);
  EXPECT_TRUE(mesh.rest_position(middle).isApprox(0.75 * mesh.rest_position(ends[0]) +
                                                  0.25 * mesh.rest_position(ends[1])));
  EXPECT_EQ(mesh.find_edge(ends[0], ends[1]), kInvalidId);
  EXPECT_NEAR(total_volume(mesh), 1.0, 1e-14);
  EXPECT_TRUE(validate(mesh).ok());
  EXPECT_TRUE(check_boundary(mesh).watertight());  // no hanging node: still conforming
}

TEST(Operations, TheFirstCutDoesNotMoveTheBodysArrays) {
  // Arrays built at exactly the body's size would all be reallocated by the first edit, a
  // copy of the whole body in one frame (core/growth.hpp): the first splits must find room.
  BoxGridOptions options;
  options.cells = {8, 8, 8};
  TetMesh mesh = make_box_grid(options);
  TetData<double> per_tet(mesh, 1.0);
  VertexData<Vec3> per_vertex(mesh, Vec3::Zero(), VertexRule::kInterpolate);
  const Tet* tets = mesh.tets().data();
  const Vec3* rest = mesh.rest_positions().data();
  const double* tet_values = per_tet.values().data();
  const Vec3* vertex_values = per_vertex.values().data();
  for (TetId t = 0; t < 20; ++t) {
    (void)split_edge(mesh, mesh.tet_edges(t * 50)[0], 0.5);
  }
  EXPECT_EQ(mesh.tets().data(), tets);
  EXPECT_EQ(mesh.rest_positions().data(), rest);
  EXPECT_EQ(per_tet.values().data(), tet_values);
  EXPECT_EQ(per_vertex.values().data(), vertex_values);
  EXPECT_TRUE(validate(mesh).ok());
}

TEST(Operations, SplitInteriorAndBoundaryFaces) {
  TetMesh mesh = grid();
  int interior = -1;
  for (int f = 0; f < 4; ++f) {
    interior = mesh.tet_neighbors(0)[f] >= 0 ? f : interior;
  }
  ASSERT_GE(interior, 0);
  const std::size_t before = mesh.tet_count();
  (void)split_face(mesh, 0, interior, {0.2, 0.3, 0.5});
  EXPECT_EQ(mesh.tet_count(), before + 4);  // two tets become six
  const std::size_t boundary_before = boundary_faces(mesh).size();
  const BoundaryFace outside = boundary_faces(mesh).front();
  (void)split_face(mesh, outside.tet, outside.local_face, {0.2, 0.3, 0.5});
  EXPECT_EQ(mesh.tet_count(), before + 6);
  EXPECT_EQ(boundary_faces(mesh).size(), boundary_before + 2);  // one boundary face became three
  EXPECT_TRUE(validate(mesh).ok());
  EXPECT_TRUE(check_boundary(mesh).watertight());
  EXPECT_NEAR(total_volume(mesh), 1.0, 1e-14);
}

TEST(Operations, SplitTetIntoFour) {
  TetMesh mesh = grid();
  const double volume = signed_volume(mesh, 5);
  const std::size_t before = mesh.tet_count();
  const VertexId center = split_tet(mesh, 5, {0.25, 0.25, 0.25, 0.25});
  EXPECT_EQ(mesh.tet_count(), before + 3);
  double sum = 0.0;
  for (TetId t : mesh.vertex_tets(center)) {
    sum += signed_volume(mesh, t);
  }
  EXPECT_NEAR(sum, volume, 1e-15);
  EXPECT_TRUE(validate(mesh).ok());
}

TEST(Operations, RefuseBadArguments) {
  TetMesh mesh = grid();
  const std::size_t tets = mesh.tet_count();
  EXPECT_THROW((void)split_edge(mesh, -1, 0.5), InputError);
  EXPECT_THROW((void)split_edge(mesh, 0, 0.0), InputError);
  EXPECT_THROW((void)split_edge(mesh, 0, 1.0), InputError);
  EXPECT_THROW((void)split_face(mesh, 0, 4, {0.3, 0.3, 0.4}), InputError);
  EXPECT_THROW((void)split_face(mesh, 0, 0, {0.3, 0.3, 0.3}), InputError);  // weights sum to 0.9
  EXPECT_THROW((void)split_tet(mesh, static_cast<TetId>(tets), {0.25, 0.25, 0.25, 0.25}),
               InputError);
  EXPECT_EQ(mesh.tet_count(), tets);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
}

TEST(Operations, CollapseUndoesAFaceSplitOntoItsEdgeSplit) {
  // Two tetrahedra on the face (a, b, c); a vertex put in the face, then the face's edge
  // (a, b) split: collapsing the face vertex onto the edge's gives exactly the edge split (four
  // tetrahedra), every tetrahedron positive, the volume, the boundary and (through the absorb
  // hook) a per-tetrahedron mass kept.
  TetMesh mesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.2, 0.3, 1), Vec3(0.3, 0.2, -1)},
               {{0, 1, 2, 3}, {0, 2, 1, 4}});
  ASSERT_TRUE(validate(mesh).ok());
  TetData<double> mass(mesh, 0.0, TetRule::kDefault);
  mass.set_hook(
      [&mesh](TetData<double>& m, TetId, std::span<const TetId> children, const double& parent) {
        double sum = 0.0;
        for (TetId c : children) {
          sum += signed_volume(mesh, c);
        }
        for (TetId c : children) {
          m[c] = parent * signed_volume(mesh, c) / sum;
        }
      });
  mass.set_absorb_hook(
      [](TetData<double>& m, TetId into, const double& removed) { m[into] += removed; });
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    mass[static_cast<TetId>(t)] = 1000.0 * signed_volume(mesh, static_cast<TetId>(t));
  }
  const double volume = total_volume(mesh);
  const double total_mass = 1000.0 * volume;
  const SurfaceEdgeCheck boundary = check_boundary(mesh);
  const int face = mesh.local_index(0, 3);  // the face opposite the apex: (a, b, c)
  const VertexId in_face = split_face(mesh, 0, face, {0.3, 0.3, 0.4});
  const VertexId on_edge = split_edge(mesh, mesh.find_edge(0, 1), 0.4);
  ASSERT_EQ(mesh.tet_count(), 8u);
  mesh.collapse_vertex(in_face, on_edge);
  EXPECT_EQ(mesh.tet_count(), 4u);
  EXPECT_TRUE(mesh.vertex_tets(in_face).empty());
  EXPECT_TRUE(validate(mesh).ok()) << validate(mesh).describe();
  EXPECT_NEAR(total_volume(mesh), volume, 1e-14);
  EXPECT_EQ(check_boundary(mesh).open_edges, boundary.open_edges);
  EXPECT_TRUE(check_boundary(mesh).watertight());
  // The total is kept exactly: each removed tetrahedron's mass goes to the one that grows over
  // its space (as a slide, the collapse moves mass between the tetrahedra of the star only).
  double sum = 0.0;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    sum += mass[static_cast<TetId>(t)];
  }
  EXPECT_NEAR(sum, total_mass, 1e-12);
  // The unreferenced vertex counts as no piece.
  EXPECT_EQ(pieces_by_vertices(mesh), 1);
}

TEST(Operations, CollapseRefusesWhatWouldBreakTheMesh) {
  TetMesh mesh = grid();
  const std::uint64_t revision = mesh.revision();
  // Not an edge.
  const Tet first = mesh.tet(0);
  VertexId far = kInvalidId;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.find_edge(first[0], static_cast<VertexId>(v)) == kInvalidId &&
        static_cast<VertexId>(v) != first[0]) {
      far = static_cast<VertexId>(v);
      break;
    }
  }
  ASSERT_NE(far, kInvalidId);
  EXPECT_THROW(mesh.collapse_vertex(first[0], far), InputError);
  EXPECT_THROW(mesh.collapse_vertex(first[0], first[0]), InputError);
  EXPECT_THROW(mesh.collapse_vertex(first[0], 100000), InputError);
  EXPECT_EQ(mesh.revision(), revision);  // nothing changed
  EXPECT_TRUE(validate(mesh).ok());
  // A lone tetrahedron has no neighbour to absorb it: collapsing any of its edges would take
  // the body away.
  TetMesh lone({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)}, {{0, 1, 2, 3}});
  EXPECT_THROW(lone.collapse_vertex(0, 1), InputError);
  EXPECT_EQ(lone.tet_count(), 1u);
}

}  // namespace
}  // namespace incise
