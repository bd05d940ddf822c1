// Scene parsing (the key contract and its errors) and running scenes.

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "incise/core/error.hpp"
#include "incise/engine/engine.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

const char* kMinimal = R"({"mesh": {"box": {"cells": [2, 2, 2]}}})";

std::string error_of(const std::string& json, const std::filesystem::path& file = "scene.json") {
  try {
    (void)parse_scene(json, file);
  } catch (const InputError& error) {
    return error.what();
  }
  return "";
}

TEST(SceneParsing, DefaultSceneIsTheSeedBlock) {
  const SceneDescription scene = default_scene();
  EXPECT_FALSE(scene.mesh_file.has_value());
  EXPECT_EQ(scene.box.cells, (std::array<int, 3>{4, 6, 4}));
  EXPECT_EQ(scene.box.tets_per_cell, 6);
  EXPECT_EQ(scene.integrator.type, IntegratorKind::kHierarchicalRungeKutta4);
  EXPECT_EQ(scene.material_name, "liver");
  EXPECT_EQ(scene.fixed.size(), 2u);
  EXPECT_GT(scene.frames, 0);
  EXPECT_EQ(scene.tool.cutter, CutterKind::kSubdivision);
  EXPECT_EQ(scene.tool.poses.size(), 2u);
}

TEST(SceneParsing, EveryExampleSceneParses) {
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes")) {
    // plan_*.json are surgical plans (incise plan), not scenes: tests/planning parses them.
    if (entry.path().extension() == ".json" &&
        !entry.path().filename().string().starts_with("plan_")) {
      EXPECT_NO_THROW((void)load_scene(entry.path())) << entry.path();
    }
  }
}

TEST(SceneParsing, LiveToolBladeDeviceAndHaptics) {
  // The default scene's blade: as long as its path's first pose, along +z of the tool frame.
  EXPECT_NEAR(default_scene().tool.blade.length, 0.048, 1e-12);
  EXPECT_EQ(default_scene().tool.device, "Scalpel");
  const SceneDescription scene = parse_scene(
      R"({"mesh": {"box": {"cells": [2, 2, 2]}},
          "tool": {"blade": {"length": 0.03, "axis": [0, 0, -2]}, "device": "Needle",
                   "haptics": {"force_limit": 2.5, "max_force_step": 0.02, "rate": 500,
                               "cutting_toughness": 80}}})",
      "scene.json");
  EXPECT_TRUE(scene.tool.poses.empty());  // a tool with no path: live only
  EXPECT_EQ(scene.tool.cutter, CutterKind::kSubdivision);
  EXPECT_DOUBLE_EQ(scene.tool.blade.length, 0.03);
  EXPECT_EQ(scene.tool.blade.axis, Vec3(0, 0, -1));
  EXPECT_EQ(scene.tool.device, "Needle");
  EXPECT_DOUBLE_EQ(scene.tool.haptics.force_limit, 2.5);
  EXPECT_DOUBLE_EQ(scene.tool.haptics.max_force_step, 0.02);
  EXPECT_DOUBLE_EQ(scene.tool.haptics.rate, 500.0);
  EXPECT_DOUBLE_EQ(scene.tool.haptics.cutting_toughness, 80.0);
  EXPECT_DOUBLE_EQ(scene.tool.haptics.contact_stiffness, 0.0);  // from the material

  for (
      const auto& [json, names] : std::vector<std::pair<std::string, std::string>>{
          {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "tool": {"blade": {"length": -1}}})",
           "tool.blade.length"},
          {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "tool": {"blade": {"axis": [0, 0, 0]}}})",
           "tool.blade.axis"},
          {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "tool": {"device": ""}})", "tool.device"},
          {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "tool": {"haptics": {"force_limt": 3}}})",
           "did you mean 'force_limit'"},
          {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "tool": {"haptics": {"rate": 1e6}}})",
           "tool.haptics.rate"},
          {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "tool": {"haptics": {"max_force_step": 0}}})",
           "tool.haptics.max_force_step"}}) {
    const std::string message = error_of(json);
    EXPECT_NE(message.find(names), std::string::npos) << json << " -> " << message;
  }
}

TEST(SceneParsing, UnknownKeyNamesFileLineAndClosestKey) {
  const std::string message = error_of(
      "{\n  \"mesh\": {\"box\": {\"cells\": [2, 2, 2]}},\n  \"integrator\": {\"type\": \"rk4\", "
      "\"dtt\": 0.01}\n}");
  EXPECT_NE(message.find("scene.json:3"), std::string::npos) << message;
  EXPECT_NE(message.find("integrator.dtt"), std::string::npos) << message;
  EXPECT_NE(message.find("did you mean 'dt'"), std::string::npos) << message;
  const std::string top =
      error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "gravty": [0, 0, -9.81]})");
  EXPECT_NE(top.find("did you mean 'gravity'"), std::string::npos) << top;
}

TEST(SceneParsing, WrongTypesAndValues) {
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "frames": "ten"})")
                .find("must be an integer"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2]}}})").find("mesh.box.cells"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "gravity": [0, -9.81]})")
                .find("three numbers"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "material": "liverr"})")
                .find("known: liver"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"type": "verlet"}})")
                .find("unknown integrator 'verlet'"),
            std::string::npos);
  EXPECT_NE(
      error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "material": {"young_modulus": -1}})")
          .find("must be positive"),
      std::string::npos);
  EXPECT_NE(error_of(R"({"integrator": {"dt": 0.01}})").find("mesh"), std::string::npos);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "fixed": [{"box": [[1, 1, 1], [0, 0, 0]]}]})")
          .find("must not exceed"),
      std::string::npos);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"dt": 0.01}, "frame_dt": 0.015})")
          .find("whole multiple"),
      std::string::npos);
}

TEST(SceneParsing, StaticSolvesPickTheirLinearSolverByDefault) {
  // Static: "auto" (factorised up to a size), with or without a solver object; dynamics: CG.
  for (const char* text :
       {R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"type": "static", "dt": 1}})",
        R"({"mesh": {"box": {"cells": [2, 2, 2]}},
            "integrator": {"type": "static", "dt": 1, "solver": {"tolerance": 1e-9}}})"}) {
    EXPECT_EQ(parse_scene(text, "static.json").integrator.static_solve.solver.type,
              LinearSolverType::kAuto)
        << text;
  }
  const SceneDescription dynamic = parse_scene(
      R"({"mesh": {"box": {"cells": [2, 2, 2]}},
          "integrator": {"type": "backward-euler", "dt": 0.01, "solver": {"tolerance": 1e-9}}})",
      "dynamic.json");
  EXPECT_EQ(dynamic.integrator.backward_euler.solver.type, LinearSolverType::kConjugateGradient);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}},
                         "integrator": {"solver": {"type": "cholesky"}}})")
                .find("auto"),
            std::string::npos)
      << "the error lists the known solvers";
}

TEST(SceneParsing, CorotationalFemKeys) {
  const SceneDescription scene = parse_scene(
      R"({"mesh": {"box": {"cells": [2, 2, 2]}},
          "model": {"type": "corotational-fem", "rayleigh": [0.1, 0.002], "assemble": false},
          "integrator": {"type": "backward-euler", "dt": 0.01, "newton_steps": 2,
                         "solver": {"type": "direct", "start_history": 3,
                                    "products": "double"}}})",
      "fem.json");
  EXPECT_EQ(scene.model_type, ModelKind::kCorotationalFem);
  EXPECT_DOUBLE_EQ(scene.fem.rayleigh_mass, 0.1);
  EXPECT_DOUBLE_EQ(scene.fem.rayleigh_stiffness, 0.002);
  EXPECT_FALSE(scene.fem.assemble);
  EXPECT_EQ(scene.fem.tangent, TangentKind::kWarped);
  EXPECT_EQ(scene.integrator.backward_euler.newton_steps, 2);
  EXPECT_EQ(scene.integrator.backward_euler.solver.type, LinearSolverType::kDirect);
  EXPECT_EQ(scene.integrator.backward_euler.solver.start_history, 3);
  EXPECT_FALSE(scene.integrator.backward_euler.solver.single_precision_products);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"solver": {"products": "half"}}})")
          .find("integrator.solver.products"),
      std::string::npos);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"solver": {"start_history": -1}}})")
          .find("integrator.solver.start_history"),
      std::string::npos);
  // A static solve defaults to the projected tangent (Newton's quadratic convergence).
  const SceneDescription statics = parse_scene(
      R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "model": {"type": "corotational-fem"},
          "integrator": {"type": "static", "tolerance": 1e-9, "max_iterations": 7,
                         "solver": {"preconditioner": "incomplete-cholesky"}}})",
      "static.json");
  EXPECT_EQ(statics.fem.tangent, TangentKind::kProjected);
  EXPECT_EQ(statics.integrator.static_solve.max_iterations, 7);
  EXPECT_EQ(statics.integrator.static_solve.solver.preconditioner,
            Preconditioner::kIncompleteCholesky);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "model": {"type": "mass-spring"},
          "integrator": {"type": "backward-euler", "solver": {"preconditioner": "two-level"}}})")
                .find("integrator.solver.preconditioner"),
            std::string::npos);
  EXPECT_EQ(
      parse_scene(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "model": {"type": "corotational-fem"},
          "integrator": {"type": "backward-euler", "solver": {"preconditioner": "two-level"}}})",
                  "two-level.json")
          .integrator.backward_euler.solver.preconditioner,
      Preconditioner::kTwoLevel);
  const std::string fem =
      R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "model": {"type": "corotational-fem", )";
  EXPECT_NE(error_of(fem + R"("rayleigh": [0.1]}})").find("model.rayleigh"), std::string::npos);
  EXPECT_NE(error_of(fem + R"("rayleigh": [-1, 0]}})").find("non-negative"), std::string::npos);
  EXPECT_NE(error_of(fem + R"("tangent": "exactish"}})").find("known: warped, projected"),
            std::string::npos);
  EXPECT_NE(error_of(fem + R"("prestrain": 0.1}})").find("mass-spring only"), std::string::npos);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "model": {"type": "mass-spring", "rayleigh": [0, 0]}})")
          .find("corotational-fem only"),
      std::string::npos);
  EXPECT_NE(error_of(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "model": {"type": "neo-hookean"}})")
                .find("known: mass-spring, corotational-fem"),
            std::string::npos);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"solver": {"preconditioner": "ilu"}}})")
          .find("known: none, jacobi, block-jacobi, incomplete-cholesky"),
      std::string::npos);
  EXPECT_NE(
      error_of(
          R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "integrator": {"solver": {"type": "gmres"}}})")
          .find("known: cg, direct"),
      std::string::npos);
}

TEST(SceneParsing, CameraKey) {
  const SceneDescription scene = parse_scene(
      R"({"mesh": {"box": {"cells": [2, 2, 2]}},
          "camera": {"eye": [0.1, -0.2, 0.3], "target": [0, 0, 0.01], "fov": 40}})",
      "scene.json");
  ASSERT_TRUE(scene.camera.has_value());
  EXPECT_EQ(scene.camera->eye, Vec3(0.1, -0.2, 0.3));
  EXPECT_EQ(scene.camera->target, Vec3(0, 0, 0.01));
  EXPECT_EQ(scene.camera->up, Vec3::UnitZ());
  EXPECT_EQ(scene.camera->fov_degrees, 40.0);
  EXPECT_FALSE(parse_scene(kMinimal, "scene.json").camera.has_value());
  const std::string box = R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "camera": )";
  EXPECT_NE(error_of(box + R"({"eye": [1, 0, 0]}})").find("camera"), std::string::npos);
  EXPECT_NE(error_of(box + R"({"eye": [1, 0, 0], "target": [1, 0, 0]}})").find("camera.eye"),
            std::string::npos);
  EXPECT_NE(error_of(box + R"({"eye": [0, 0, 1], "target": [0, 0, 0]}})").find("camera.up"),
            std::string::npos);
  EXPECT_NE(
      error_of(box + R"({"eye": [1, 0, 0], "target": [0, 0, 0], "fov": 180}})").find("camera.fov"),
      std::string::npos);
  EXPECT_NE(error_of(box + R"({"eye": [1, 0, 0], "target": [0, 0, 0], "zoom": 2}})").find("zoom"),
            std::string::npos);
}

TEST(SceneParsing, ACutterWithoutAToolWaitsForALiveOne) {
  const SceneDescription scene =
      parse_scene(R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "cutter": {"type": "subdivision"}})",
                  "scene.json");
  EXPECT_EQ(scene.tool.cutter, CutterKind::kSubdivision);
  EXPECT_TRUE(scene.tool.poses.empty());
  Engine engine(scene);
  auto live = std::make_unique<LiveToolPose>();
  LiveToolPose& hand = *live;
  engine.set_tool_source(std::move(live));
  const std::size_t tets = engine.mesh().tet_count();
  for (int k = 0; k <= 10; ++k) {
    const double x = -0.002 + 0.0022 * k;
    hand.set({0.0, Vec3(x, 0.013, 0.01), Vec3(x, 0.013, 0.05)});
    ASSERT_TRUE(engine.step());
  }
  EXPECT_GT(engine.mesh().tet_count(), tets);
}

TEST(SceneParsing, MalformedJsonNamesTheLine) {
  const std::string message =
      error_of("{\n  \"mesh\": {\"box\": {\"cells\": [2, 2, 2]}},\n  \"frames\": 10,\n}\n");
  EXPECT_NE(message.find("malformed JSON"), std::string::npos) << message;
  EXPECT_NE(message.find("scene.json:4"), std::string::npos) << message;
  // A number beyond a double (found by fuzzing: it escaped as nlohmann's out_of_range, naming
  // no file).
  const std::string overflow = error_of("{\n  \"frames\": 22E22200\n}\n");
  EXPECT_NE(overflow.find("scene.json:2: malformed JSON: number overflow parsing '22E22200'"),
            std::string::npos)
      << overflow;
}

TEST(SceneParsing, RelativePathsResolveAgainstTheSceneFile) {
  const SceneDescription scene =
      parse_scene(R"({"mesh": {"file": "meshes/body.msh"}, "output": {"dir": "results"}})",
                  "/data/scenes/a.json");
  EXPECT_EQ(*scene.mesh_file, std::filesystem::path("/data/scenes/meshes/body.msh"));
  EXPECT_EQ(scene.output_dir, std::filesystem::path("/data/scenes/results"));
}

TEST(SceneParsing, MinimalSceneGetsDefaults) {
  const SceneDescription scene = parse_scene(kMinimal, "m.json");
  EXPECT_EQ(scene.material_name, "liver");
  EXPECT_EQ(scene.frame_dt, scene.integrator.dt);
  EXPECT_TRUE(scene.gravity.isZero());
}

TEST(SceneParsing, RegionsThatSelectNothingAreErrors) {
  const SceneDescription scene = parse_scene(
      R"({"mesh": {"box": {"cells": [2, 2, 2]}}, "fixed": [{"box": [[5, 5, 5], [6, 6, 6]]}]})",
      "r.json");
  try {
    Engine engine(scene);
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("fixed[0] selects no vertex"), std::string::npos)
        << error.what();
  }
}

/// Runs `frames` frames into a ParaView series in `dir` (every `every`-th frame, first, last).
RunResult run_to(Engine& engine, int frames, const std::filesystem::path& dir,
                 const std::string& name, int every, std::filesystem::path* pvd = nullptr) {
  VtuSeriesSink series(dir, name, every, frames);
  engine.add_sink(series);
  if (pvd != nullptr) {
    *pvd = series.pvd();
  }
  return run(engine, frames);
}

TEST(Simulation, SameSceneSameBytes) {
  const auto dir = test::scratch_dir("deterministic");
  for (const char* run : {"a", "b"}) {
    Engine engine(default_scene());
    const RunResult result = run_to(engine, 40, dir / run, "default", 10);
    ASSERT_FALSE(result.diverged);
  }
  std::size_t compared = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir / "a")) {
    const auto twin = dir / "b" / entry.path().filename();
    ASSERT_TRUE(std::filesystem::exists(twin)) << twin;
    EXPECT_EQ(test::file_bytes(entry.path()), test::file_bytes(twin)) << entry.path().filename();
    ++compared;
  }
  EXPECT_EQ(compared, 6u);  // the .pvd and frames 0, 5, 10, 15, 20
}

TEST(Simulation, DivergenceStopsAndKeepsWrittenFrames) {
  SceneDescription scene = parse_scene(test::kDivergingScene, "diverging.json");
  Engine engine(scene);
  ASSERT_FALSE(engine.warnings().empty());
  EXPECT_NE(engine.warnings().front().find("stability limit"), std::string::npos);
  const auto dir = test::scratch_dir("diverging");
  std::filesystem::path pvd_path;
  const RunResult result = run_to(engine, 200, dir, "diverging", 1, &pvd_path);
  ASSERT_TRUE(result.diverged);
  EXPECT_NE(result.divergence.find("diverged in frame"), std::string::npos) << result.divergence;
  EXPECT_LT(result.frames.size(), 200u);
  // Every frame listed in the series exists and holds only finite numbers (read back).
  const std::string pvd = test::file_bytes(pvd_path);
  for (const FrameRecord& record : result.frames) {
    EXPECT_TRUE(std::isfinite(record.kinetic_energy));
  }
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == ".vtu") {
      EXPECT_NE(pvd.find(entry.path().filename().string()), std::string::npos);
      const TetMesh frame = read_tet_mesh(entry.path()).mesh;
      for (const Vec3& p : frame.rest_positions()) {
        ASSERT_TRUE(p.allFinite()) << entry.path();
      }
    }
  }
}

/// The 576-tet block was cut, and stayed valid, watertight and of the same mass (kg).
void expect_cut_and_intact(const Engine& simulation, double mass) {
  const TetMesh& mesh = simulation.mesh();
  EXPECT_GT(mesh.tet_count(), 576u);
  EXPECT_TRUE(validate(mesh).ok()) << validate(mesh).describe();
  EXPECT_TRUE(check_boundary(mesh).watertight());
  EXPECT_NEAR(simulation.total_mass(), mass, 1e-9 * mass);
}

/// How far apart (m) the copies a cut made have moved from their originals: the wound's opening.
double widest_opening(const Engine& simulation, std::size_t* copies = nullptr) {
  const TetMesh& mesh = simulation.mesh();
  double widest = 0.0;
  std::size_t count = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const VertexOrigin& origin = mesh.vertex_origin(static_cast<VertexId>(v));
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      ++count;
      widest = std::max(widest, (simulation.state().x.values()[v] -
                                 simulation.state().x.values()[origin.parents[0]])
                                    .norm());
    }
  }
  if (copies != nullptr) {
    *copies = count;
  }
  return widest;
}

TEST(Simulation, CorotationalFemFollowsTheCutAndTheWoundOpens) {
  Engine simulation(
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "fem_cut_pull.json"));
  const double mass = simulation.total_mass();
  const RunResult result = run_to(simulation, 160, test::scratch_dir("fem-cut"), "fem_cut", 80);
  ASSERT_FALSE(result.diverged) << result.divergence;
  expect_cut_and_intact(simulation, mass);
  const double widest = widest_opening(simulation);
  std::printf("FEM block under a 4 mm pull: the cut lips part by %.2f mm\n", widest * 1e3);
  EXPECT_GT(widest, 0.5e-3);  // m: the lips part under the pull
  EXPECT_LT(widest, 1e-2);
}

TEST(Simulation, DefaultSceneCutsTheBlockAndTheWoundOpens) {
  Engine simulation(default_scene());
  const double mass = simulation.total_mass();
  const RunResult result = run_to(simulation, 150, test::scratch_dir("fig10"), "default", 50);
  ASSERT_FALSE(result.diverged) << result.divergence;
  expect_cut_and_intact(simulation, mass);
  const TetMesh& mesh = simulation.mesh();
  int components = 0;
  (void)tet_components(mesh, &components);
  EXPECT_EQ(components, 1);  // the blade stops 1.2 cm above the bottom: an incision, not a split
  // The wound opens: copies made by the cut have moved apart from their originals.
  std::size_t copies = 0;
  const double widest = widest_opening(simulation, &copies);
  EXPECT_GT(copies, 20u);
  EXPECT_GT(widest, 1e-3);  // m: the lips part by more than a millimetre
  EXPECT_LT(widest, 2e-2);
  EXPECT_GT(result.frames[50].cd + result.frames[50].gc, 0.0);  // the cut stages ran
}

TEST(Simulation, MassIsConservedAndTheBlockSettles) {
  Engine simulation(
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "block_press.json"));
  const double mass = simulation.total_mass();
  EXPECT_NEAR(mass, 1060.0 * 0.04 * 0.06 * 0.04, 1e-12);  // kg: liver density times volume
  const RunResult result = run_to(simulation, 150, test::scratch_dir("settle"), "default", 50);
  ASSERT_FALSE(result.diverged);
  const FrameRecord& last = result.frames.back();
  EXPECT_LT(last.kinetic_energy, 1e-12);
  EXPECT_GT(last.max_displacement, 1e-3);  // the press shows
  EXPECT_LT(last.max_displacement, 1e-2);  // and stays small against the 4 cm block
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(SceneReference, NamesEveryKeyTheParserAccepts) {
  // scenes/README.md is the scene reference: every key the parser takes, at every place, must
  // be in it (as `key` or "key"), so the two cannot drift apart.
  const std::string reference =
      test::file_bytes(std::string(INCISE_SOURCE_DIR) + "/scenes/README.md");
  const nlohmann::json base = nlohmann::json::parse(default_scene_text());
  const nlohmann::json box = {{0, 0, 0}, {1, 1, 1}};
  std::vector<std::pair<std::string, nlohmann::json>> probes;
  const auto probe = [&](const std::string& where,
                         const std::function<void(nlohmann::json&)>& put) {
    nlohmann::json scene = base;
    put(scene);
    probes.emplace_back(where, scene);
  };
  const nlohmann::json unknown = {{"zz_unknown", 1}};
  probe("top", [](nlohmann::json& s) { s["zz_unknown"] = 1; });
  probe("mesh", [](nlohmann::json& s) { s["mesh"]["zz_unknown"] = 1; });
  probe("mesh.box", [](nlohmann::json& s) { s["mesh"]["box"]["zz_unknown"] = 1; });
  probe("material", [](nlohmann::json& s) {
    s["material"] = {
        {"young_modulus", 1e3}, {"poisson_ratio", 0.3}, {"density", 1e3}, {"zz_unknown", 1}};
  });
  probe("materials", [&](nlohmann::json& s) {
    s["materials"] = {{{"material", "fat"}, {"region", {{"box", box}}}, {"zz_unknown", 1}}};
  });
  probe("materials.region", [&](nlohmann::json& s) {
    s["materials"] = {{{"material", "fat"}, {"region", {{"box", box}, {"zz_unknown", 1}}}}};
  });
  probe("model", [](nlohmann::json& s) { s["model"]["zz_unknown"] = 1; });
  probe("damping", [](nlohmann::json& s) { s["damping"]["zz_unknown"] = 1; });
  probe("integrator", [](nlohmann::json& s) { s["integrator"]["zz_unknown"] = 1; });
  probe("integrator.solver", [&](nlohmann::json& s) { s["integrator"]["solver"] = unknown; });
  probe("fixed", [](nlohmann::json& s) { s["fixed"][0]["zz_unknown"] = 1; });
  probe("displacements", [&](nlohmann::json& s) {
    s["displacements"] = {{{"box", box}, {"displacement", {0, 0, 0}}, {"zz_unknown", 1}}};
  });
  probe("forces", [&](nlohmann::json& s) {
    s["forces"] = {{{"box", box}, {"force", {0, 0, 0}}, {"zz_unknown", 1}}};
  });
  probe("tool", [](nlohmann::json& s) { s["tool"]["zz_unknown"] = 1; });
  probe("tool.blade", [&](nlohmann::json& s) { s["tool"]["blade"] = unknown; });
  probe("tool.haptics", [&](nlohmann::json& s) { s["tool"]["haptics"] = unknown; });
  probe("cutter", [](nlohmann::json& s) { s["cutter"]["zz_unknown"] = 1; });
  probe("output", [](nlohmann::json& s) { s["output"]["zz_unknown"] = 1; });
  probe("camera", [&](nlohmann::json& s) { s["camera"] = unknown; });
  probe("visual", [&](nlohmann::json& s) { s["visual"] = unknown; });
  std::size_t checked = 0;
  for (const auto& [where, probed] : probes) {
    const nlohmann::json& scene = probed;  // clang 14 cannot capture a structured binding
    const std::vector<std::string> keys = test::keys_listed_as_valid(
        [&] { (void)parse_scene(scene.dump(), "probe.json"); }, scene.dump());
    EXPECT_GE(keys.size(), 1u) << where;
    for (const std::string& key : keys) {
      EXPECT_TRUE(test::names_key(reference, key))
          << "scenes/README.md does not name the key " << where << "." << key;
      ++checked;
    }
  }
  EXPECT_GT(checked, 80u);
}

}  // namespace
}  // namespace incise
