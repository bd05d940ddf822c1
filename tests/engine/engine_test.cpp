// The engine as something you step and feed from outside: tool-pose sources (scripted,
// recorded and replayed, live from another thread), frame sinks, published snapshots.

#include "incise/engine/engine.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
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

TEST(LiveToolPose, KeepsTheStrokesEndsThatFellBetweenTwoFrames) {
  LiveToolPose tool;
  const auto at = [](double y) { return BladePose{0.0, Vec3(0, y, 0), Vec3(0, y, 1)}; };
  const auto tip_y = [](const std::optional<BladePose>& pose) {
    return pose ? pose->tip.y() : -1.0;  // -1: a lift
  };
  // Between two frames: a stroke from 1 to 2, lifted, and another from 3 to 4 still going.
  for (const double y : {1.0, 1.5, 2.0}) {
    tool.set(at(y));
  }
  tool.lift();
  tool.set(at(3.0));
  tool.set(at(4.0));
  EXPECT_TRUE(tool.has_passed());
  ToolMotion motion = tool.motion(7, 0.07);
  ASSERT_EQ(motion.passed.size(), 4u);
  EXPECT_EQ(tip_y(motion.passed[0]), 1.0);  // where the first stroke began
  EXPECT_EQ(tip_y(motion.passed[1]), 2.0);  // where it was lifted
  EXPECT_EQ(tip_y(motion.passed[2]), -1.0);
  EXPECT_EQ(tip_y(motion.passed[3]), 3.0);  // where the second began
  EXPECT_EQ(tip_y(motion.pose), 4.0);
  EXPECT_EQ(motion.pose->time, 0.07);  // stamped by the engine's clock
  EXPECT_EQ(motion.passed[0]->time, 0.07);
  EXPECT_FALSE(tool.has_passed());
  // The stroke goes on: only where it is now.
  tool.set(at(5.0));
  motion = tool.motion(8, 0.08);
  EXPECT_TRUE(motion.passed.empty());
  EXPECT_EQ(tip_y(motion.pose), 5.0);
  // Lifted where the engine last saw it: the lift alone. A stroke that begins at the newest
  // pose is that pose alone.
  tool.lift();
  tool.set(at(6.0));
  motion = tool.motion(9, 0.09);
  ASSERT_EQ(motion.passed.size(), 1u);
  EXPECT_EQ(tip_y(motion.passed[0]), -1.0);
  EXPECT_EQ(tip_y(motion.pose), 6.0);
  // Moved, then lifted: where it was lifted, then the lift.
  tool.set(at(6.5));
  tool.lift();
  motion = tool.motion(10, 0.1);
  ASSERT_EQ(motion.passed.size(), 2u);
  EXPECT_EQ(tip_y(motion.passed[0]), 6.5);
  EXPECT_EQ(tip_y(motion.passed[1]), -1.0);
  EXPECT_FALSE(motion.pose.has_value());
  // A device that flickers while the engine stalls holds bounded memory, newest ends kept.
  for (int k = 0; k < 1000; ++k) {
    tool.set(at(k));
    tool.lift();
  }
  motion = tool.motion(11, 0.11);
  EXPECT_EQ(motion.passed.size(), LiveToolPose::kMaxPassed);
  EXPECT_EQ(tip_y(motion.passed[motion.passed.size() - 2]), 999.0);
  EXPECT_FALSE(motion.pose.has_value());
}

// What a live stroke cuts does not depend on when the physics looked: a loaded machine that
// steps once while a device plays its whole stroke (here: set and lifted between two frames)
// still cuts from where the stroke began to where it was lifted, and a full cut separates.
TEST(Engine, AStrokeBetweenTwoFramesCutsAsFarAsOneSampledEveryFrame) {
  const auto pose_at_y = [](double y) {
    return BladePose{0.0, Vec3(0.0213, y, -0.01), Vec3(0.0213, y, 0.05)};
  };
  const auto cut_by = [&](bool every_frame) {
    SceneDescription scene = short_default(0);
    scene.tool.poses.clear();
    auto engine = std::make_unique<Engine>(scene);
    auto live = std::make_unique<LiveToolPose>();
    LiveToolPose* tool = live.get();
    engine->set_tool_source(std::move(live));
    EXPECT_TRUE(engine->step());
    for (int k = 0; k <= 40; ++k) {
      tool->set(pose_at_y(-0.01 + 0.002 * k));
      if (every_frame) {
        EXPECT_TRUE(engine->step());
      }
    }
    tool->lift();
    EXPECT_TRUE(engine->step());
    // Sampled every frame, the lift comes where the engine already was: nothing left to cut.
    EXPECT_EQ(engine->last_frame().cut, !every_frame);
    EXPECT_FALSE(engine->blade().has_value());
    return engine;
  };
  const auto sampled = cut_by(true);
  const auto between = cut_by(false);
  EXPECT_EQ(between->blade_passed().size(), 3u);  // began, lifted, the lift
  for (const Engine* engine : {sampled.get(), between.get()}) {
    EXPECT_TRUE(validate(engine->mesh()).ok());
    int pieces = 0;
    (void)tet_components(engine->mesh(), &pieces);
    EXPECT_EQ(pieces, 2);
  }
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
                        "model": {"type": "corotational-fem"}, "gravity": [0, 0, -9.81],
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
    // The frame's record counts the solver's iterations: none for an explicit scheme.
    ASSERT_TRUE(engine.step());
    const FrameRecord& record = engine.last_frame();
    EXPECT_EQ(record.solver_iterations > 0, implicit) << type;
    // And where backward Euler's relaxation went: parts of rx, each measured.
    if (std::string(type) == "backward-euler") {
      const FrameRecord::RelaxationParts& parts = record.rx_parts;
      EXPECT_GT(parts.forces, 0.0);
      EXPECT_GT(parts.products, 0.0);
      EXPECT_GT(parts.vector_updates, 0.0);
      EXPECT_LE(parts.refresh + parts.forces + parts.preconditioner + parts.start + parts.products +
                    parts.vector_updates,
                record.rx);
    }
  }
}

TEST(Engine, ABladePoseFarOffInItsPathIsHarmless) {
  // A path (a device's, or a file's) may hold a pose far off: the cell numbers of the cutters'
  // grids did not fit a long there (undefined behaviour, found with UBSan). Each cutter's scene,
  // its path given a pose 1e30 m away halfway: every frame steps, the mesh stays valid, and
  // the path's parts in the body still cut.
  for (const char* name : {"default.json", "xfem_cut_pull.json"}) {
    SCOPED_TRACE(name);
    SceneDescription scene = load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / name);
    ASSERT_GE(scene.tool.poses.size(), 2u);
    const BladePose start = scene.tool.poses.front();
    const BladePose end = scene.tool.poses.back();
    const double middle = 0.5 * (start.time + end.time);
    BladePose far = pose_at(scene.tool.poses, middle);
    far.tip.y() = 1e30;
    far.base.y() = -1e30;
    BladePose before = pose_at(scene.tool.poses, middle - 0.02);
    BladePose after = pose_at(scene.tool.poses, middle + 0.02);
    far.time = middle;
    scene.tool.poses = {start, before, far, after, end};
    Engine engine(scene);
    const std::size_t tets_in = engine.mesh().tet_count();
    const int frames = static_cast<int>(std::ceil((end.time + 0.05) / scene.frame_dt));
    for (int k = 0; k < frames; ++k) {
      ASSERT_TRUE(engine.step()) << engine.divergence();
    }
    EXPECT_TRUE(validate(engine.mesh()).ok());
    EXPECT_GT(engine.mesh().tet_count(), tets_in);
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
