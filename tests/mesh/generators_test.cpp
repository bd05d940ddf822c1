// Box grids: counts, volume, conformity and orientation for 5 and 6 tets per cell.

#include "incise/mesh/generators.hpp"

#include <gtest/gtest.h>

#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/quality.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {
namespace {

class BoxGrid : public ::testing::TestWithParam<std::tuple<int, int, int, int>> {};

TEST_P(BoxGrid, ConformingPositiveAndExact) {
  const auto [nx, ny, nz, per_cell] = GetParam();
  BoxGridOptions options;
  options.cells = {nx, ny, nz};
  options.size = Vec3(0.04, 0.06, 0.04);  // m
  options.origin = Vec3(-0.02, 0.0, 1.0);
  options.tets_per_cell = per_cell;
  const TetMesh mesh = make_box_grid(options);
  EXPECT_EQ(mesh.vertex_count(), static_cast<std::size_t>((nx + 1) * (ny + 1) * (nz + 1)));
  EXPECT_EQ(mesh.tet_count(), static_cast<std::size_t>(nx * ny * nz * per_cell));
  EXPECT_NEAR(total_volume(mesh), 0.04 * 0.06 * 0.04, 1e-15);
  const auto report = validate(mesh);
  EXPECT_TRUE(report.ok()) << report.describe();
  EXPECT_TRUE(report.unreferenced_vertices.empty());
  // Conforming: the boundary is exactly two triangles per boundary cell face.
  const auto faces = boundary_faces(mesh);
  EXPECT_EQ(faces.size(), static_cast<std::size_t>(4 * (nx * ny + ny * nz + nx * nz)));
  EXPECT_TRUE(check_boundary(mesh).watertight());
  int components = 0;
  (void)tet_components(mesh, &components);
  EXPECT_EQ(components, 1);
  // Interior faces: (4 * tets - boundary faces) / 2, each a neighbour pair.
  std::size_t neighbor_links = 0;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    for (TetId n : mesh.tet_neighbors(static_cast<TetId>(t))) {
      neighbor_links += n >= 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(neighbor_links, 4 * mesh.tet_count() - faces.size());
}

INSTANTIATE_TEST_SUITE_P(Sizes, BoxGrid,
                         ::testing::Values(std::make_tuple(1, 1, 1, 6), std::make_tuple(1, 1, 1, 5),
                                           std::make_tuple(2, 2, 2, 6), std::make_tuple(2, 2, 2, 5),
                                           std::make_tuple(4, 6, 4, 6), std::make_tuple(3, 4, 5, 5),
                                           std::make_tuple(7, 1, 3, 5)));

TEST(BoxGrid, SeedTableOneSizes) {
  // The seed's Table 1 grids: 2x2x2, 2x4x3 and 4x6x4 cells with 6 tets each.
  for (const auto& [cells, tets] :
       {std::pair{std::array{2, 2, 2}, 48}, std::pair{std::array{2, 4, 3}, 144},
        std::pair{std::array{4, 6, 4}, 576}}) {
    BoxGridOptions options;
    options.cells = cells;
    EXPECT_EQ(make_box_grid(options).tet_count(), static_cast<std::size_t>(tets));
  }
}

TEST(BoxGrid, KuhnCellQuality) {
  BoxGridOptions options;
  const auto quality = summarize_quality(make_box_grid(options));
  // Every Kuhn tet is congruent: min dihedral 45 degrees... the path tets have 45 deg angles.
  EXPECT_NEAR(quality.min_dihedral_deg, 45.0, 1e-9);
  EXPECT_NEAR(quality.max_dihedral_deg, 45.0, 1e-9);
}

TEST(BoxGrid, RejectsBadOptions) {
  BoxGridOptions options;
  options.cells = {0, 1, 1};
  EXPECT_THROW((void)make_box_grid(options), InputError);
  options.cells = {1, 1, 1};
  options.tets_per_cell = 4;
  EXPECT_THROW((void)make_box_grid(options), InputError);
  options.tets_per_cell = 6;
  options.size = Vec3(1, -1, 1);
  EXPECT_THROW((void)make_box_grid(options), InputError);
}

}  // namespace
}  // namespace incise
