// The engine as something you step and feed from outside: tool-pose sources (scripted,
// recorded and replayed, live from another thread), frame sinks, published snapshots.

#include "incise/engine/engine.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/solve/integrators.hpp"
#include "scene_support.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

using test::short_default;

TEST(Engine, StepsFrameByFrameAndCutsAlongTheScenePath) {
  Engine engine(short_default(60));
  EXPECT_EQ(engine.frame(), 0);
  const std::size_t tets_in = engine.mesh().tet_count();
  int cutting_frames = 0;
  for (int k = 1; k <= 60; ++k) {
    ASSERT_TRUE(engine.step()) << engine.divergence();
    EXPECT_EQ(engine.frame(), k);
    EXPECT_DOUBLE_EQ(engine.time(), 0.01 * k);
    cutting_frames += engine.last_frame().cut ? 1 : 0;
    ASSERT_TRUE(engine.blade().has_value());
  }
  EXPECT_EQ(cutting_frames, 60);
  EXPECT_GT(engine.mesh().tet_count(), tets_in);
  EXPECT_TRUE(validate(engine.mesh()).ok());
  // The cut surface is part of the boundary and not empty once the blade is in.
  const std::vector<Triangle> cut = engine.cut_surface();
  EXPECT_GT(cut.size(), 10u);
  EXPECT_LT(cut.size(), boundary_faces(engine.mesh()).size());
}

TEST(Engine, ARecordedToolPathReplaysTheSameRunBitForBit) {
  const auto dir = test::scratch_dir("replay");
  std::vector<Vec3> first;
  {
    Engine engine(short_default(40));
    ToolPathRecorder recorder(dir / "tool.csv");
    engine.add_sink(recorder);
    (void)run(engine, 40);
    EXPECT_EQ(recorder.poses().size(), 41u);  // frame 0 and every frame after
    first.assign(engine.positions().begin(), engine.positions().end());
  }
  // The replay runs the same scene without its path, from the recorded file.
  SceneDescription scene = short_default(40);
  scene.tool.poses.clear();
  Engine engine(scene);
  engine.set_tool_source(ScriptedToolPath::from_csv(dir / "tool.csv"));
  (void)run(engine, 40);
  ASSERT_EQ(engine.positions().size(), first.size());
  for (std::size_t i = 0; i < first.size(); ++i) {
    ASSERT_EQ(engine.positions()[i], first[i]) << "vertex " << i;
  }
}

TEST(Engine, ALiveToolCutsWhereItIsSetAndALiftStartsANewStroke) {
  SceneDescription scene = short_default(0);
  scene.tool.poses.clear();
  Engine engine(scene);
  auto live = std::make_unique<LiveToolPose>();
  LiveToolPose* tool = live.get();
  engine.set_tool_source(std::move(live));
  // A vertical blade moved by another thread (a viewer, a device) across half the block.
  const auto pose_at_y = [](double y) {
    return BladePose{0.0, Vec3(0.0213, y, 0.012), Vec3(0.0213, y, 0.06)};
  };
  for (int k = 0; k <= 20; ++k) {
    std::thread mover([&] { tool->set(pose_at_y(-0.01 + 0.002 * k)); });
    mover.join();
    ASSERT_TRUE(engine.step());
    EXPECT_EQ(engine.last_frame().cut, k > 0) << "frame " << k + 1;
  }
  const std::size_t tets_after_stroke = engine.mesh().tet_count();
  EXPECT_GT(tets_after_stroke, 576u);
  // Lifted: frames without a blade; set again elsewhere: a new stroke starts there (its first
  // frame cuts nothing: the blade did not sweep across the gap).
  tool->lift();
  ASSERT_TRUE(engine.step());
  EXPECT_FALSE(engine.last_frame().cut);
  EXPECT_FALSE(engine.blade().has_value());
  tool->set(pose_at_y(0.05));
  ASSERT_TRUE(engine.step());
  EXPECT_FALSE(engine.last_frame().cut);
  EXPECT_EQ(engine.mesh().tet_count(), tets_after_stroke);
  EXPECT_TRUE(validate(engine.mesh()).ok());
}

TEST(Engine, ReadersOnAnotherThreadSeeWholeFramesWhileItSteps) {
  Engine engine(short_default(80));
  engine.publish_snapshots(true);
  std::atomic<bool> done{false};
  std::atomic<int> seen{0};
  std::atomic<int> bad{0};
  std::thread reader([&] {
    int last_frame = -1;
    while (!done.load()) {
      const std::shared_ptr<const Snapshot> snapshot = engine.snapshots().latest();
      if (!snapshot || snapshot->frame == last_frame) {
        std::this_thread::yield();
        continue;
      }
      // A whole frame: the surface refers to positions that exist, all finite, and frames
      // only go forward.
      bool ok = snapshot->frame > last_frame && snapshot->surface != nullptr &&
                snapshot->surface->on_cut.size() == snapshot->surface->triangles.size();
      for (const Triangle& triangle : snapshot->surface->triangles) {
        for (VertexId v : triangle) {
          ok = ok && static_cast<std::size_t>(v) < snapshot->positions.size() &&
               snapshot->positions[static_cast<std::size_t>(v)].allFinite();
        }
      }
      bad += ok ? 0 : 1;
      last_frame = snapshot->frame;
      ++seen;
    }
  });
  for (int k = 0; k < 80; ++k) {
    ASSERT_TRUE(engine.step());
  }
  done = true;
  reader.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_GT(seen.load(), 0);
  // The last snapshot is the last frame, with the cut faces marked.
  const auto last = engine.snapshots().latest();
  ASSERT_TRUE(last);
  EXPECT_EQ(last->frame, 80);
  std::size_t cut = 0;
  for (std::uint8_t flag : last->surface->on_cut) {
    cut += flag;
  }
  EXPECT_EQ(cut, engine.cut_surface().size());
  EXPECT_GT(cut, 0u);
}

TEST(Engine, EachIntegratorKnowsWhetherItIsImplicitAndItsStabilityLimit) {
  for (const char* type : {"symplectic-euler", "rk4", "backward-euler", "static"}) {
    const SceneDescription scene = parse_scene(
        std::string(R"({"mesh": {"box": {"cells": [2, 2, 2], "size": [0.01, 0.01, 0.01]}},
                        "fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}],
                        "model": {"type": "corotational-fem"},
                        "integrator": {"type": ")") +
            type + R"(", "dt": 0.001}})",
        "integrators.json");
    Engine engine(scene);
    const bool implicit = std::string(type) == "backward-euler" || std::string(type) == "static";
    EXPECT_EQ(engine.integrator().implicit(), implicit) << type;
    EXPECT_EQ(std::isinf(engine.stability_limit()), implicit) << type;
    if (!implicit) {
      EXPECT_GT(engine.stability_limit(), 0.0);
    }
  }
}

TEST(Engine, ADivergedFrameIsNotHandedToSinksAndStepStops) {
  SceneDescription scene = parse_scene(test::kDivergingScene, "diverging.json");
  Engine engine(scene);
  struct Counter final : FrameSink {
    int frames = 0;
    bool frame(const Engine& e, const FrameRecord&) override {
      ++frames;
      for (const Vec3& x : e.positions()) {
        EXPECT_TRUE(x.allFinite());
      }
      return false;
    }
  } counter;
  engine.add_sink(counter);
  int stepped = 0;
  while (engine.step()) {
    ++stepped;
    ASSERT_LT(stepped, 200);
  }
  EXPECT_TRUE(engine.diverged());
  EXPECT_EQ(counter.frames, stepped);
  EXPECT_FALSE(engine.step());  // stays stopped
  EXPECT_NE(engine.divergence().find("diverged in frame"), std::string::npos);
}

}  // namespace
}  // namespace incise
