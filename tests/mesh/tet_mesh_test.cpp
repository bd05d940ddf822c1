// Unit tests of TetMesh adjacency and the edit operations on small hand-made meshes.

#include "incise/mesh/tet_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

/// Two positive tetrahedra sharing the face (1, 2, 3).
TetMesh two_tets() {
  return TetMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(1, 1, 1)},
                 {Tet{0, 1, 2, 3}, Tet{4, 1, 3, 2}});
}

TEST(TetMesh, BulkAdjacencyOfTwoTets) {
  const TetMesh mesh = two_tets();
  EXPECT_EQ(mesh.vertex_count(), 5u);
  EXPECT_EQ(mesh.tet_count(), 2u);
  EXPECT_EQ(mesh.edge_count(), 9u);        // 6 + 6 - 3 shared
  EXPECT_EQ(mesh.tet_neighbors(0)[0], 1);  // face opposite vertex 0 is (1,2,3)
  EXPECT_EQ(mesh.tet_neighbors(1)[0], 0);
  for (int f = 1; f < 4; ++f) {
    EXPECT_EQ(mesh.tet_neighbors(0)[f], kBoundaryFace);
    EXPECT_EQ(mesh.tet_neighbors(1)[f], kBoundaryFace);
  }
  const EdgeId shared = mesh.find_edge(2, 1);
  ASSERT_NE(shared, kInvalidId);
  EXPECT_EQ(mesh.edge_tets(shared).size(), 2u);
  EXPECT_EQ(mesh.find_edge(0, 4), kInvalidId);
  EXPECT_EQ(mesh.vertex_tets(1).size(), 2u);
  EXPECT_TRUE(validate(mesh).ok()) << validate(mesh).describe();
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
}

TEST(TetMesh, RejectsBadIdsInBulkConstruction) {
  EXPECT_THROW(TetMesh({Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY()}, {Tet{0, 1, 2, 3}}),
               InputError);
  EXPECT_THROW(
      TetMesh({Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()}, {Tet{0, 1, 1, 3}}),
      InputError);
}

TEST(TetMesh, DuplicateVertexOpensSharedFace) {
  TetMesh mesh = two_tets();
  const std::uint64_t before = mesh.revision();
  // Give tet 1 its own copies of the shared face's vertices: the face becomes boundary twice.
  for (VertexId v : {1, 2, 3}) {
    const std::array<TetId, 1> moved{1};
    mesh.duplicate_vertex(v, moved);
  }
  EXPECT_GT(mesh.revision(), before);
  EXPECT_EQ(mesh.vertex_count(), 8u);
  EXPECT_EQ(mesh.tet_neighbors(0)[0], kBoundaryFace);
  EXPECT_EQ(mesh.tet_neighbors(1)[0], kBoundaryFace);
  EXPECT_EQ(mesh.edge_count(), 12u);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
  int components = 0;
  (void)tet_components(mesh, &components);
  EXPECT_EQ(components, 2);
  EXPECT_EQ(mesh.vertex_origin(7).kind, VertexOrigin::Kind::kDuplicate);
  EXPECT_EQ(mesh.vertex_origin(7).parents[0], 3);
  EXPECT_TRUE(check_boundary(mesh).watertight());
}

TEST(TetMesh, DuplicateVertexRejectsTetWithoutTheVertex) {
  TetMesh mesh = two_tets();
  const std::array<TetId, 1> moved{1};
  EXPECT_THROW(mesh.duplicate_vertex(0, moved), InputError);  // tet 1 does not use vertex 0
  EXPECT_EQ(mesh.vertex_count(), 5u);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
}

TEST(TetMesh, ReplaceTetKeepsParentIdForFirstChild) {
  TetMesh mesh = two_tets();
  // Split tet 0 at its centroid (1:4).
  const std::array<VertexId, 4> parents{0, 1, 2, 3};
  const std::array<double, 4> weights{0.25, 0.25, 0.25, 0.25};
  const VertexId center = mesh.add_vertex(parents, weights);
  EXPECT_TRUE(mesh.rest_position(center).isApprox(Vec3(0.25, 0.25, 0.25)));
  const Tet parent = mesh.tet(0);
  std::vector<Tet> children;
  for (int i = 0; i < 4; ++i) {
    Tet child = parent;
    child[i] = center;
    children.push_back(child);
  }
  const auto ids = mesh.replace_tet(0, children);
  ASSERT_EQ(ids.size(), 4u);
  EXPECT_EQ(ids[0], 0);
  EXPECT_EQ(ids[1], 2);
  EXPECT_EQ(mesh.tet_count(), 5u);
  EXPECT_NEAR(total_volume(mesh), 1.0 / 6.0 + 1.0 / 3.0, 1e-14);
  EXPECT_TRUE(validate(mesh).ok()) << validate(mesh).describe();
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
  // The child keeping face (1,2,3) still neighbours tet 1.
  const auto& n1 = mesh.tet_neighbors(1);
  EXPECT_GE(n1[0], 0);
  EXPECT_EQ(mesh.tet(n1[0])[0], center);
}

TEST(TetMesh, AddVertexChecksWeights) {
  TetMesh mesh = two_tets();
  const std::array<VertexId, 2> parents{0, 1};
  const std::array<double, 2> bad_sum{0.5, 0.6};
  const std::array<double, 2> negative{1.5, -0.5};
  EXPECT_THROW(mesh.add_vertex(parents, bad_sum), InputError);
  EXPECT_THROW(mesh.add_vertex(parents, negative), InputError);
  const std::array<VertexId, 2> missing{0, 99};
  const std::array<double, 2> half{0.5, 0.5};
  EXPECT_THROW(mesh.add_vertex(missing, half), InputError);
  EXPECT_EQ(mesh.vertex_count(), 5u);
}

TEST(TetMesh, RelocatedVertexKeepsItsTetsAndValuesFollow) {
  // A vertex on the shared face (as a cutter puts one on the blade line) slides within it:
  // the tetrahedra stay, the total volume stays, and interpolated values are taken again.
  TetMesh mesh = two_tets();
  VertexData<Vec3> position(mesh, Vec3::Zero());
  VertexData<double> label(mesh, 0.0);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    position[static_cast<VertexId>(v)] = 2.0 * mesh.rest_position(static_cast<VertexId>(v));
    label[static_cast<VertexId>(v)] = static_cast<double>(v);
  }
  const double volume = total_volume(mesh);
  const std::array<VertexId, 3> face{1, 2, 3};
  const std::array<double, 3> centre{1.0 / 3, 1.0 / 3, 1.0 / 3};
  const VertexId slider = mesh.add_vertex(face, centre);
  const std::array<double, 3> towards_1{0.6, 0.2, 0.2};
  // Each tetrahedron's face (1, 2, 3) fanned around the new vertex.
  for (TetId t : {0, 1}) {
    const Tet tet = mesh.tet(t);
    const auto& f = tet_local::kFaces[0];
    const std::array<Tet, 3> parts{Tet{tet[0], tet[f[0]], tet[f[1]], slider},
                                   Tet{tet[0], tet[f[1]], tet[f[2]], slider},
                                   Tet{tet[0], tet[f[2]], tet[f[0]], slider}};
    (void)mesh.replace_tet(t, parts);
  }
  ASSERT_TRUE(validate(mesh).ok());
  const std::vector<TetId> around(mesh.vertex_tets(slider).begin(), mesh.vertex_tets(slider).end());
  const std::uint64_t revision = mesh.revision();
  mesh.relocate_vertex(slider, face, towards_1);
  EXPECT_GT(mesh.revision(), revision);
  EXPECT_TRUE(mesh.rest_position(slider).isApprox(Vec3(0.6, 0.2, 0.2)));
  std::vector<TetId> after(mesh.vertex_tets(slider).begin(), mesh.vertex_tets(slider).end());
  std::sort(after.begin(), after.end());
  std::vector<TetId> before = around;
  std::sort(before.begin(), before.end());
  EXPECT_EQ(after, before);
  EXPECT_TRUE(validate(mesh).ok());
  EXPECT_NEAR(total_volume(mesh), volume, 1e-15);
  EXPECT_TRUE(position[slider].isApprox(2.0 * mesh.rest_position(slider)));
  EXPECT_NEAR(label[slider], 0.6 * 1 + 0.2 * 2 + 0.2 * 3, 1e-12);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
  const std::array<double, 3> bad{0.7, 0.7, -0.4};
  EXPECT_THROW(mesh.relocate_vertex(slider, face, bad), InputError);
}

TEST(TetMesh, RemoveTetSwapsLastIntoHole) {
  TetMesh mesh = two_tets();
  TetData<int> label(mesh, -1);
  label[0] = 10;
  label[1] = 11;
  mesh.remove_tet(0);
  ASSERT_EQ(mesh.tet_count(), 1u);
  EXPECT_EQ(label.size(), 1u);
  EXPECT_EQ(label[0], 11);
  EXPECT_EQ(mesh.edge_count(), 6u);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
  const auto report = validate(mesh);
  EXPECT_EQ(report.unreferenced_vertices, std::vector<VertexId>{0});
}

TEST(TetMesh, NonManifoldFaceIsMarkedAndHealed) {
  // Three tetrahedra on one face: two on one side would overlap, the mesh is invalid.
  TetMesh mesh = two_tets();
  const VertexId extra = mesh.add_vertex(Vec3(2, 2, 2));
  const TetId third = mesh.add_tet({extra, 1, 3, 2});
  EXPECT_EQ(mesh.tet_neighbors(0)[0], kNonManifoldFace);
  EXPECT_EQ(mesh.tet_neighbors(1)[0], kNonManifoldFace);
  EXPECT_EQ(mesh.tet_neighbors(third)[0], kNonManifoldFace);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
  EXPECT_EQ(validate(mesh).nonmanifold_faces.size(), 1u);
  mesh.remove_tet(third);
  EXPECT_EQ(mesh.tet_neighbors(0)[0], 1);
  EXPECT_EQ(mesh.tet_neighbors(1)[0], 0);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
}

TEST(TetMesh, AnObservedMeshStaysWhereItIsAndItsDestructionIsAnnounced) {
  // The ownership rule: attributes and models hold the mesh's address, so a mesh they observe
  // is never moved, nor overwritten; the attempt is refused before anything changes.
  TetMesh mesh = two_tets();
  VertexData<double> weight(mesh, 1.0);
  EXPECT_THROW({ TetMesh moved(std::move(mesh)); }, InternalError);
  EXPECT_EQ(mesh.tet_count(), 2u);
  EXPECT_EQ(weight.mesh(), &mesh);
  TetMesh other = two_tets();
  EXPECT_THROW(other = std::move(mesh), InternalError);
  EXPECT_THROW(mesh = two_tets(), InternalError);
  EXPECT_EQ(mesh.tet_count(), 2u);
  mesh.add_vertex(Vec3(3, 3, 3));
  EXPECT_EQ(weight.size(), 6u);
  // An attribute may move: it goes on following the same mesh.
  VertexData<double> relocated = std::move(weight);
  mesh.add_vertex(Vec3(4, 4, 4));
  EXPECT_EQ(relocated.size(), 7u);
  // A mesh nobody observes moves freely (a reader's result into its place).
  TetMesh fresh = two_tets();
  TetMesh placed = std::move(fresh);
  EXPECT_EQ(placed.tet_count(), 2u);
  // Observers that outlive their mesh are told, and do not touch it afterwards.
  auto owned = std::make_unique<TetMesh>(two_tets());
  VertexData<int> survivor(*owned, 0);
  owned.reset();
  EXPECT_EQ(survivor.mesh(), nullptr);
}

TEST(Attributes, VertexRules) {
  TetMesh mesh = two_tets();
  VertexData<Vec3> interpolated(mesh, Vec3::Zero());
  VertexData<double> copied(mesh, -1.0, VertexRule::kCopy);
  VertexData<double> defaulted(mesh, -1.0, VertexRule::kDefault);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    interpolated[static_cast<VertexId>(v)] = mesh.rest_position(static_cast<VertexId>(v));
    copied[static_cast<VertexId>(v)] = static_cast<double>(v);
    defaulted[static_cast<VertexId>(v)] = static_cast<double>(v);
  }
  const std::array<VertexId, 2> parents{1, 4};
  const std::array<double, 2> weights{0.25, 0.75};
  const VertexId blended = mesh.add_vertex(parents, weights);
  EXPECT_TRUE(interpolated[blended].isApprox(mesh.rest_position(blended), 1e-15));
  EXPECT_EQ(copied[blended], 4.0);  // the heaviest parent
  EXPECT_EQ(defaulted[blended], -1.0);
  const std::array<TetId, 1> moved{1};
  const VertexId copy = mesh.duplicate_vertex(4, moved);
  EXPECT_TRUE(interpolated[copy].isApprox(interpolated[4]));
  EXPECT_EQ(copied[copy], 4.0);
  EXPECT_EQ(defaulted[copy], -1.0);
  const VertexId fresh = mesh.add_vertex(Vec3(5, 5, 5));
  EXPECT_TRUE(interpolated[fresh].isZero());
}

TEST(Attributes, HookCanConserveASplitQuantity) {
  TetMesh mesh = two_tets();
  VertexData<double> mass(mesh, 0.0, VertexRule::kDefault);
  mass.fill(2.0);
  // Split the original's mass evenly with its duplicate.
  mass.set_hook([](VertexData<double>& data, VertexId vertex, const VertexOrigin& origin) {
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      data[origin.parents[0]] *= 0.5;
      data[vertex] = data[origin.parents[0]];
    }
  });
  const std::array<TetId, 1> moved{1};
  mesh.duplicate_vertex(2, moved);
  double total = 0.0;
  for (double m : mass.values()) {
    total += m;
  }
  EXPECT_DOUBLE_EQ(total, 10.0);
  EXPECT_DOUBLE_EQ(mass[5], 1.0);
}

TEST(Attributes, EdgeRulesOnASplitEdge) {
  TetMesh mesh = two_tets();
  EdgeData<double> length(mesh, -1.0, EdgeRule::kScale);
  EdgeData<double> copied(mesh, -1.0, EdgeRule::kCopy);
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& ends = mesh.edge(static_cast<EdgeId>(e));
    length[static_cast<EdgeId>(e)] =
        (mesh.rest_position(ends[0]) - mesh.rest_position(ends[1])).norm();
    copied[static_cast<EdgeId>(e)] = 7.0;
  }
  // Split edge (1, 2), shared by both tetrahedra, at 30 %.
  const std::array<VertexId, 2> parents{1, 2};
  const std::array<double, 2> weights{0.7, 0.3};
  const VertexId middle = mesh.add_vertex(parents, weights);
  for (TetId t : std::vector<TetId>(mesh.edge_tets(mesh.find_edge(1, 2)).begin(),
                                    mesh.edge_tets(mesh.find_edge(1, 2)).end())) {
    Tet first = mesh.tet(t);
    Tet second = mesh.tet(t);
    std::replace(first.begin(), first.end(), 2, middle);
    std::replace(second.begin(), second.end(), 1, middle);
    const std::array<Tet, 2> children{first, second};
    mesh.replace_tet(t, children);
  }
  EXPECT_EQ(mesh.find_edge(1, 2), kInvalidId);
  EXPECT_EQ(mesh.compare_with_rebuilt_adjacency(), "");
  ASSERT_EQ(length.size(), mesh.edge_count());
  const EdgeId near_piece = mesh.find_edge(1, middle);
  const EdgeId far_piece = mesh.find_edge(middle, 2);
  EXPECT_NEAR(length[near_piece], 0.3 * std::sqrt(2.0), 1e-14);
  EXPECT_NEAR(length[far_piece], 0.7 * std::sqrt(2.0), 1e-14);
  EXPECT_EQ(copied[near_piece], 7.0);
  // Edges from the new vertex to the apexes have no parent edge: default value.
  EXPECT_EQ(copied[mesh.find_edge(middle, 0)], -1.0);
}

}  // namespace
}  // namespace incise
