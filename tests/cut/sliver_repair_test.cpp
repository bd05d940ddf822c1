// `incise convert --fix-slivers`: flat tetrahedra and slivers of every kind are collapsed away,
// the mesh stays valid and watertight, its volume and boundary move by no more than the
// slivers' own size; a mesh without slivers is left as it is.

#include "incise/mesh/sliver_repair.hpp"

#include <gtest/gtest.h>

#include "../sliver_meshes.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

TEST(SliverRepair, EveryKindFlatOrThinIsCollapsedAway) {
  for (const std::string& kind : test::sliver_kinds()) {
    for (const double height : {0.0, 1e-9}) {  // flat (zero volume), or a sliver
      TetMesh mesh = test::grid_with_sliver(kind, height);
      const ValidationReport before = validate(mesh);
      ASSERT_EQ(before.degenerate_tets.size() + before.sliver_tets.size(), 1u)
          << kind << " " << height << "\n"
          << before.describe();
      const double volume = total_volume(mesh);
      const SliverRepairResult result = fix_slivers(mesh);
      EXPECT_EQ(result.flat_before + result.slivers_before, 1u);
      EXPECT_GE(result.collapses, 1u) << kind;
      EXPECT_EQ(result.flat_after, 0u) << kind << " " << height;
      EXPECT_EQ(result.slivers_after, 0u) << kind << " " << height;
      // A flat one goes with the boundary exactly kept; a sliver 1e-9 m high moves it by a few
      // of its heights at most (measured: 1-3).
      EXPECT_LE(result.boundary_shift, 10.0 * height) << kind;
      const ValidationReport after = validate(mesh);
      EXPECT_TRUE(after.ok()) << kind << " " << height << "\n" << after.describe();
      EXPECT_TRUE(after.unreferenced_vertices.empty());
      EXPECT_TRUE(check_boundary(mesh).watertight()) << kind;
      // The sliver's volume is below 1e-9 x 0.01^2 m^3: nothing else changed.
      EXPECT_NEAR(total_volume(mesh), volume, 1e-12) << kind;
    }
  }
}

TEST(SliverRepair, DataMeshesWithoutSliversAreLeftAsTheyAre) {
  for (const char* name : {"sofa/liver.msh", "pbd/armadillo_4k.ele", "libigl/octopus-low.mesh"}) {
    TetMesh mesh = read_tet_mesh(test::data_file(name)).mesh;
    const std::size_t tets = mesh.tet_count();
    const SliverRepairResult result = fix_slivers(mesh);
    EXPECT_EQ(result.flat_before + result.slivers_before, 0u) << name;
    EXPECT_EQ(result.collapses, 0u) << name;
    EXPECT_EQ(mesh.tet_count(), tets) << name;
  }
}

}  // namespace
}  // namespace incise
