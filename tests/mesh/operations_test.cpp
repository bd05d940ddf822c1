// Conforming split operators: counts, volume, conformity, and refusals.

#include "incise/mesh/operations.hpp"

#include <gtest/gtest.h>

#include "incise/core/error.hpp"
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

}  // namespace
}  // namespace incise
