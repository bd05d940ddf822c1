// Checkpoints: a run resumed from one continues bit for bit as if it had never stopped, on
// every example scene (with and without cutting); damaged checkpoints give clear errors.

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "incise/core/error.hpp"
#include "incise/core/state_archive.hpp"
#include "incise/engine/engine.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

std::vector<std::filesystem::path> example_scenes() {
  std::vector<std::filesystem::path> scenes;
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes")) {
    // plan_*.json are surgical plans, not scenes.
    if (entry.path().extension() == ".json" &&
        !entry.path().filename().string().starts_with("plan_")) {
      scenes.push_back(entry.path());
    }
  }
  std::sort(scenes.begin(), scenes.end());
  return scenes;
}

/// Steps until `frame` (stopping early only at a divergence, which the test reports).
void step_to(Engine& engine, int frame) {
  while (engine.frame() < frame) {
    ASSERT_TRUE(engine.step()) << engine.divergence();
  }
}

/// Runs `scene` to `total` straight, and again stopping at `stop`, saving a checkpoint and
/// resuming from it: the two end bit for bit alike, in memory and in the file they write. With
/// a cutter, the stop must fall mid-cut.
void expect_resumes_bit_for_bit(const SceneDescription& scene, int stop, int total,
                                const std::filesystem::path& dir, const std::string& name) {
  Engine straight(scene);
  step_to(straight, total);

  Engine first(scene);
  const std::size_t tets_before = first.mesh().tet_count();
  step_to(first, stop);
  const auto checkpoint = dir / (name + ".ck");
  first.save_checkpoint(checkpoint);
  const std::unique_ptr<Engine> resumed = Engine::resume(checkpoint);
  EXPECT_EQ(resumed->frame(), stop);
  if (first.cutter() != nullptr) {
    EXPECT_GT(first.mesh().tet_count(), tets_before) << "the stop should fall mid-cut";
  }
  step_to(*resumed, total);

  ASSERT_EQ(resumed->mesh().tet_count(), straight.mesh().tet_count());
  ASSERT_EQ(resumed->positions().size(), straight.positions().size());
  for (std::size_t v = 0; v < straight.positions().size(); ++v) {
    ASSERT_EQ(resumed->positions()[v], straight.positions()[v]) << "vertex " << v;
    ASSERT_EQ(resumed->state().v.values()[v], straight.state().v.values()[v]) << "vertex " << v;
  }
  // The frame written by either is the same file, byte for byte.
  VtuSeriesSink a(dir / (name + "-straight"), "frame");
  VtuSeriesSink b(dir / (name + "-resumed"), "frame");
  a.begin(straight);
  b.begin(*resumed);
  const std::string file = "frame_" + std::string(6 - std::to_string(total).size(), '0') +
                           std::to_string(total) + ".vtu";
  EXPECT_EQ(test::file_bytes(dir / (name + "-straight") / file),
            test::file_bytes(dir / (name + "-resumed") / file));
}

TEST(Checkpoint, EveryExampleSceneResumesBitForBit) {
  const auto dir = test::scratch_dir("checkpoint");
  int scenes = 0;
  for (const auto& path : example_scenes()) {
    SCOPED_TRACE(path.filename().string());
    const SceneDescription scene = load_scene(path);
    // Short runs keep the suite fast; the stop falls mid-cut in both cutting scenes (the blade
    // enters the block at frames 15 and 45), with blade-line vertices pending.
    const int total = std::min(scene.frames, 64);
    expect_resumes_bit_for_bit(scene, total * 3 / 4, total, dir, path.stem().string());
    ++scenes;
  }
  EXPECT_GE(scenes, 7);
}

TEST(Checkpoint, TheTwoLevelPreconditionerResumesBitForBit) {
  // Its clusters follow each cut and its coarse factor is kept for ten steps, so it carries
  // state from step to step: a resumed run that built it afresh would solve with another
  // preconditioner, to the same tolerance but not to the same bits. A block pulled and cut
  // (as scenes/fem_cut_pull.json) at two sizes (6 and 60 aggregates); the stop falls mid-cut,
  // between two factorisations. (Three levels: TwoLevelPreconditioner.ItsStateSaved...)
  const auto dir = test::scratch_dir("checkpoint-two-level");
  for (const char* cells : {"[4, 6, 4]", "[10, 14, 10]"}) {
    SCOPED_TRACE(cells);
    const SceneDescription scene =
        parse_scene(std::string(R"({"mesh": {"box": {"cells": )") + cells +
                        R"(, "size": [0.04, 0.06, 0.04], "tets_per_cell": 6}},
          "material": "liver", "model": {"type": "corotational-fem", "rayleigh": [1.0, 0.01]},
          "integrator": {"type": "backward-euler", "dt": 0.01,
                         "solver": {"type": "cg", "preconditioner": "two-level",
                                    "tolerance": 1e-6}},
          "fixed": [{"box": [[-1, -1, -1], [0.0001, 1, 1]]}],
          "displacements": [{"box": [[0.0399, -1, -1], [1, 1, 1]],
                             "displacement": [0.004, 0, 0], "ramp_time": 0.3}],
          "gravity": [0, 0, -9.81],
          "tool": {"poses": [[0.3, 0.0213, -0.012, 0.012, 0.0213, -0.012, 0.06],
                             [1.3, 0.0213, 0.072, 0.012, 0.0213, 0.072, 0.06]]},
          "cutter": {"type": "subdivision"}, "frames": 62, "frame_dt": 0.01})",
                    "two_level_cut.json");
    expect_resumes_bit_for_bit(scene, 45, 62, dir, std::string("cells") + cells[1]);
  }
}

TEST(Checkpoint, AnXfemCutThatCrossesItselfResumesBitForBit) {
  // Soak finding 501075: at frame 30 the blade crosses near its own cut and three elements
  // take copies of their own (a corner's first copy went with a piece the cut took off). The
  // stop at 32 falls after them: the resumed cutter must know them, or its next split near
  // them makes yet another copy.
  const auto dir = test::scratch_dir("checkpoint-xfem-crossing");
  const SceneDescription scene =
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) /
                 "tests/data/soak_findings/fixed/seed-501075/scene.json");
  expect_resumes_bit_for_bit(scene, 32, 40, dir, "crossing");
}

TEST(Checkpoint, DamagedFilesGiveClearErrors) {
  const auto dir = test::scratch_dir("checkpoint-damaged");
  SceneDescription scene = default_scene();
  Engine engine(scene);
  step_to(engine, 20);
  engine.save_checkpoint(dir / "good.ck");
  const std::string good = test::file_bytes(dir / "good.ck");

  const auto expect_error = [&](const std::string& bytes, const std::string& expected) {
    std::ofstream(dir / "bad.ck", std::ios::binary) << bytes;
    try {
      (void)Engine::resume(dir / "bad.ck");
      FAIL() << "no error for: " << expected;
    } catch (const InputError& error) {
      const std::string what = error.what();
      EXPECT_NE(what.find(expected), std::string::npos) << what;
      EXPECT_NE(what.find("bad.ck"), std::string::npos) << what;
    }
  };
  expect_error("", "not an incise checkpoint");
  expect_error("hello world, not a checkpoint at all", "not an incise checkpoint");
  expect_error(good.substr(0, good.size() / 2), "truncated");
  std::string flipped = good;
  flipped[flipped.size() / 2] = static_cast<char>(flipped[flipped.size() / 2] ^ 0x20);
  expect_error(flipped, "checksum");
  std::string version = good;
  version[std::string("INCISE-CHECKPOINT\n").size()] = 9;
  expect_error(version, "checkpoint format 9");
  try {
    (void)Engine::resume(dir / "missing.ck");
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("cannot open"), std::string::npos);
  }
  // The good one still resumes.
  EXPECT_EQ(Engine::resume(dir / "good.ck")->frame(), 20);
}

TEST(Checkpoint, AYesNoValueThatIsNeitherIsRefused) {
  // Found by fuzzing the state behind a valid header (fuzz target checkpoint_state): a byte
  // other than 0 or 1 read as a bool is undefined behaviour, so the reader refuses it.
  StateWriter out;
  out.value<std::uint8_t>(1);
  out.value<std::uint8_t>(101);
  StateReader in(out.bytes(), "state.ck");
  EXPECT_TRUE(in.value<bool>("blade present"));
  try {
    (void)in.value<bool>("cutter present");
    FAIL() << "101 read as a bool";
  } catch (const InputError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find("state.ck"), std::string::npos) << what;
    EXPECT_NE(what.find("cutter present"), std::string::npos) << what;
    EXPECT_NE(what.find("101"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace incise
