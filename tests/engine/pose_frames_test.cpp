// Blade poses given in the world (a mouse on the picture, a tracked device) are carried back
// to the body's rest frame before the cutters cut: exactly under affine motion, and the cut
// then lands where the body is now, not where it was at rest.

#include "incise/engine/pose_frames.hpp"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <memory>

#include "incise/engine/engine.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/scene/scene.hpp"

namespace incise {
namespace {

TEST(PoseFrames, AnAffinelyMovedBodyMapsBackExactlyWhereverTheBladeIs) {
  BoxGridOptions box;
  box.cells = {3, 4, 2};
  box.size = Vec3(0.03, 0.04, 0.02);
  const TetMesh mesh = make_box_grid(box);
  Mat3 a;
  a << 1.1, 0.2, 0.0, -0.1, 0.9, 0.05, 0.0, 0.1, 1.2;  // stretch, shear, turn
  const Vec3 b(0.02, -0.01, 0.03);
  std::vector<Vec3> x;
  for (const Vec3& rest : mesh.rest_positions()) {
    x.push_back(a * rest + b);
  }
  const Mat3 inverse = a.inverse();
  for (const BladePose& world :
       {BladePose{0.0, a * Vec3(0.015, 0.02, 0.005) + b, a * Vec3(0.015, 0.02, 0.05) + b},
        BladePose{0.0, a * Vec3(0.001, 0.039, 0.019) + b, a * Vec3(-0.02, 0.06, 0.04) + b},
        // Outside the body: the nearest element's map, the same affine one.
        BladePose{0.0, Vec3(0.5, 0.5, 0.5), Vec3(0.6, 0.5, 0.5)}}) {
    const std::optional<RestMap> map = blade_rest_map(mesh, x, world);
    ASSERT_TRUE(map.has_value());
    EXPECT_LT((map->linear - inverse).norm(), 1e-12);
    const BladePose rest = mapped(world, *map);
    EXPECT_LT((rest.tip - inverse * (world.tip - b)).norm(), 1e-12);
    EXPECT_LT((rest.base - inverse * (world.base - b)).norm(), 1e-12);
  }
}

/// A block moved 2 cm along x and 1 cm up (every vertex prescribed), cut by a vertical blade
/// swept along y through the plane x = 0.0213 + shift of the world, given in `frame`.
std::unique_ptr<Engine> cut_moved_block(const std::string& cutter, PoseFrame frame) {
  const std::string text = R"({
    "mesh": {"box": {"cells": [4, 6, 4], "size": [0.04, 0.06, 0.04], "tets_per_cell": 6}},
    "material": "liver", "model": {"type": "corotational-fem"},
    "integrator": {"type": "backward-euler", "dt": 0.01},
    "displacements": [{"box": [[-1, -1, -1], [1, 1, 1]], "displacement": [0.02, 0, 0.01],
                       "ramp_time": 0.05}],
    "cutter": {"type": ")" +
                           cutter + R"("}, "frames": 60, "frame_dt": 0.01})";
  auto engine = std::make_unique<Engine>(parse_scene(text, "moved_block.json"));
  auto live = std::make_unique<LiveToolPose>(frame);
  LiveToolPose* tool = live.get();
  engine->set_tool_source(std::move(live));
  for (int k = 0; k < 10; ++k) {  // the move ramps in over 5 frames
    EXPECT_TRUE(engine->step());
  }
  const Vec3 shift(0.02, 0.0, 0.01);
  for (int k = 0; k <= 44; ++k) {
    const double y = -0.01 + 0.002 * k;
    tool->set(BladePose{0.0, Vec3(0.0213, y, -0.012) + shift, Vec3(0.0213, y, 0.06) + shift});
    EXPECT_TRUE(engine->step());
  }
  return engine;
}

TEST(PoseFrames, AWorldBladeCutsWhereTheBodyIsNow) {
  for (const char* cutter : {"subdivision", "xfem"}) {
    SCOPED_TRACE(cutter);
    const auto engine = cut_moved_block(cutter, PoseFrame::kWorld);
    EXPECT_TRUE(validate(engine->mesh()).ok());
    int pieces = 0;
    (void)tet_components(engine->mesh(), &pieces);
    EXPECT_EQ(pieces, 2) << "a full cut through the moved block separates it";
    EXPECT_EQ(engine->blade_frame(), PoseFrame::kWorld);
    EXPECT_EQ(engine->blade_world()->tip, engine->blade()->tip);  // drawn where it is held
    ASSERT_TRUE(engine->blade_rest().has_value());
    EXPECT_NEAR(engine->blade_rest()->tip.x(), 0.0213, 1e-12);
    if (std::string(cutter) == "subdivision") {
      // The cut faces lie in the rest plane the world blade swept through.
      const std::vector<Triangle> cut = engine->cut_surface();
      ASSERT_FALSE(cut.empty());
      for (const Triangle& face : cut) {
        for (VertexId v : face) {
          EXPECT_NEAR(engine->mesh().rest_position(v).x(), 0.0213, 1e-9);
        }
      }
    }
  }
  // The same hand path read as rest-frame poses (as every live pose was before) sweeps the
  // plane x = 0.0413 of the rest block, just outside it: the body the user sees is not cut.
  const auto misread = cut_moved_block("subdivision", PoseFrame::kRest);
  EXPECT_TRUE(misread->cut_surface().empty());
  // A rest-frame blade is drawn where the body carries it: 2 cm along x and 1 cm up.
  ASSERT_TRUE(misread->blade_world().has_value());
  EXPECT_LT((misread->blade_world()->tip - misread->blade()->tip - Vec3(0.02, 0.0, 0.01)).norm(),
            1e-12);
  int pieces = 0;
  (void)tet_components(misread->mesh(), &pieces);
  EXPECT_EQ(pieces, 1);
}

}  // namespace
}  // namespace incise
