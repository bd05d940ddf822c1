// Issue 40: a mesh with slivers (positive volume) is cut, not refused.

#include <gtest/gtest.h>

#include "blade_walks.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "sliver_meshes.hpp"

namespace incise {
namespace {

TEST(SliverInput, EveryKindIsUsableAndCutThroughItSeparates) {
  for (const std::string& kind : test::sliver_kinds()) {
    SCOPED_TRACE(kind);
    TetMesh mesh = test::grid_with_sliver(kind);
    const auto sliver = static_cast<TetId>(mesh.tet_count() - 1);
    ASSERT_EQ(
        orient3d(mesh.rest_position(mesh.tet(sliver)[0]), mesh.rest_position(mesh.tet(sliver)[1]),
                 mesh.rest_position(mesh.tet(sliver)[2]), mesh.rest_position(mesh.tet(sliver)[3])),
        Sign::kPositive);
    const ValidationReport before = validate(mesh);
    EXPECT_EQ(before.sliver_tets, std::vector<TetId>{sliver});
    EXPECT_TRUE(before.usable()) << before.describe();
    EXPECT_TRUE(before.degenerate_tets.empty());
    // A vertical blade across the whole body at the sliver's place: the body comes apart in
    // two, and every pose leaves a mesh no worse than slivers (the cutters' predicates are
    // exact, so the sliver is cut like any tetrahedron).
    const double volume = total_volume(mesh);
    const int pieces = pieces_by_vertices(mesh);
    const test::Box box = test::bounds(mesh);
    Vec3 centre = Vec3::Zero();
    for (VertexId v : mesh.tet(sliver)) {
      centre += mesh.rest_position(v) / 4.0;
    }
    const double through = (centre.y() - box.low.y()) / (box.high.y() - box.low.y());
    const std::size_t tets_before = mesh.tet_count();
    SubdivisionCutter cutter(mesh);
    test::play(cutter, test::sweep_along_x(box, through, 1.05, 24, 0.05, 0.04),
               [&](std::size_t pose) {
                 const ValidationReport report = validate(mesh);
                 EXPECT_TRUE(report.usable()) << "pose " << pose << ": " << report.describe();
               });
    EXPECT_GT(mesh.tet_count(), tets_before);
    EXPECT_NEAR(total_volume(mesh), volume, 1e-9 * volume);
    EXPECT_EQ(pieces_by_vertices(mesh), pieces + 1);
  }
}

}  // namespace
}  // namespace incise
