// validate() must catch each kind of defect and name the elements involved.

#include "incise/mesh/validate.hpp"

#include <gtest/gtest.h>

#include <limits>

#include "incise/mesh/generators.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

TetMesh small_grid() {
  BoxGridOptions options;
  options.cells = {2, 1, 1};
  return make_box_grid(options);
}

TEST(Validate, CleanGridPasses) {
  const auto report = validate(small_grid());
  EXPECT_TRUE(report.ok()) << report.describe();
  EXPECT_EQ(report.problem_count(), 0u);
  EXPECT_TRUE(report.unreferenced_vertices.empty());
}

TEST(Validate, FindsInvertedTet) {
  const TetMesh good = small_grid();
  std::vector<Tet> tets(good.tets().begin(), good.tets().end());
  std::swap(tets[3][0], tets[3][1]);
  const TetMesh mesh(std::vector<Vec3>(good.rest_positions().begin(), good.rest_positions().end()),
                     tets);
  const auto report = validate(mesh);
  EXPECT_FALSE(report.ok());
  EXPECT_EQ(report.inverted_tets, std::vector<TetId>{3});
  EXPECT_NE(report.describe().find("inverted tetrahedra: 3"), std::string::npos)
      << report.describe();
}

TEST(Validate, FindsDegenerateTetsAndToleratesSlivers) {
  // Exactly flat: degenerate, not usable. Nearly flat (normalised volume 1e-9) but of positive
  // volume: a sliver, usable (every mesher leaves some), though not ok() (a cut's output must
  // have none).
  TetMesh flat({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}, {Tet{0, 1, 2, 3}});
  EXPECT_EQ(validate(flat).degenerate_tets, std::vector<TetId>{0});
  EXPECT_FALSE(validate(flat).usable());
  TetMesh sliver({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.3, 0.3, 1e-9)},
                 {Tet{0, 1, 2, 3}});
  const ValidationReport report = validate(sliver);
  EXPECT_TRUE(report.degenerate_tets.empty());
  EXPECT_EQ(report.sliver_tets, std::vector<TetId>{0});
  EXPECT_TRUE(report.usable());
  EXPECT_FALSE(report.ok());
  EXPECT_NE(report.describe().find("slivers"), std::string::npos) << report.describe();
  EXPECT_TRUE(validate(sliver, {.degenerate_tolerance = 1e-12}).ok());
}

TEST(Validate, FindsNonFiniteCoordinates) {
  TetMesh mesh = test::unit_tet();
  mesh.set_rest_position(2, Vec3(0, std::numeric_limits<double>::quiet_NaN(), 0));
  const auto report = validate(mesh);
  EXPECT_EQ(report.nonfinite_vertices, std::vector<VertexId>{2});
  EXPECT_FALSE(report.ok());
  mesh.set_rest_position(2, Vec3(0, std::numeric_limits<double>::infinity(), 0));
  EXPECT_EQ(validate(mesh).nonfinite_vertices, std::vector<VertexId>{2});
}

TEST(Validate, FindsDuplicateAndNonManifold) {
  TetMesh mesh = test::unit_tet();
  mesh.add_tet({0, 1, 2, 3});
  const auto report = validate(mesh);
  EXPECT_EQ(report.duplicate_tets.size(), 1u);
  EXPECT_EQ(report.duplicate_tets[0], (std::pair<TetId, TetId>{0, 1}));
  // Two identical tets share all four faces with each other, and overlap.
  EXPECT_FALSE(report.overlapping_tets.empty());
  mesh.add_tet({1, 0, 2, 3});  // inverted, and the third tet on every face
  const auto worse = validate(mesh);
  EXPECT_EQ(worse.nonmanifold_faces.size(), 4u);
  EXPECT_EQ(worse.inverted_tets, std::vector<TetId>{2});
}

TEST(Validate, FindsOverlappingNeighbours) {
  // Two positive tets on the same side of their shared face.
  TetMesh mesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(0.1, 0.1, 0.1)},
               {Tet{0, 1, 2, 3}, Tet{4, 1, 2, 3}});
  ASSERT_GT(signed_volume(mesh, 1), 0.0);
  const auto report = validate(mesh);
  EXPECT_EQ(report.overlapping_tets.size(), 1u);
}

TEST(Validate, ReportsUnreferencedVerticesButToleratesThem) {
  TetMesh mesh = test::unit_tet();
  mesh.add_vertex(Vec3(5, 5, 5));
  const auto report = validate(mesh);
  EXPECT_EQ(report.unreferenced_vertices, std::vector<VertexId>{4});
  EXPECT_TRUE(report.ok());
}

TEST(Validate, AMeshOfManyBlocksIsReportedInTetrahedronOrderWithDuplicatesAcrossBlocks) {
  // validate() checks blocks of 4096 tetrahedra on worker threads and sorts each block's
  // vertex sets apart before merging them: defects in several blocks, and duplicates of
  // tetrahedra in the first block appended at the end, must come out as one thread finds
  // them (ascending ids; every duplicate pair).
  BoxGridOptions options;
  options.cells = {14, 14, 14};  // 16,464 tetrahedra: five blocks
  const TetMesh good = make_box_grid(options);
  std::vector<Tet> tets(good.tets().begin(), good.tets().end());
  ASSERT_GT(tets.size(), 4u * 4096u);
  const std::vector<TetId> inverted{5, 4500, 9000, 16000};
  for (TetId t : inverted) {
    std::swap(tets[static_cast<std::size_t>(t)][0], tets[static_cast<std::size_t>(t)][1]);
  }
  const std::vector<std::size_t> copied{1, 300, 4095, 4096, 12000};
  for (std::size_t t : copied) {
    Tet copy = tets[t];
    std::swap(copy[0], copy[3]);  // the same set in another order (and inverted)
    tets.push_back(copy);
  }
  const TetMesh mesh(std::vector<Vec3>(good.rest_positions().begin(), good.rest_positions().end()),
                     tets);
  const ValidationReport report = validate(mesh);
  std::vector<TetId> expected_inverted = inverted;
  for (std::size_t k = 0; k < copied.size(); ++k) {
    expected_inverted.push_back(static_cast<TetId>(good.tet_count() + k));
  }
  EXPECT_EQ(report.inverted_tets, expected_inverted);
  // Duplicates as a plain sort of (sorted set, id) finds them.
  std::vector<std::pair<Tet, TetId>> keys;
  for (std::size_t t = 0; t < tets.size(); ++t) {
    Tet key = tets[t];
    std::sort(key.begin(), key.end());
    keys.emplace_back(key, static_cast<TetId>(t));
  }
  std::sort(keys.begin(), keys.end());
  std::vector<std::pair<TetId, TetId>> expected_duplicates;
  for (std::size_t i = 1; i < keys.size(); ++i) {
    if (keys[i].first == keys[i - 1].first) {
      expected_duplicates.emplace_back(keys[i - 1].second, keys[i].second);
    }
  }
  ASSERT_EQ(expected_duplicates.size(), copied.size());
  EXPECT_EQ(report.duplicate_tets, expected_duplicates);
  EXPECT_TRUE(report.degenerate_tets.empty());
}

}  // namespace
}  // namespace incise
