// XFEM in the engine (scene cutter "xfem" with the corotational FEM): the block under tension
// opens along the cut while mass is conserved and the mesh stays valid; on every real mesh a
// full cut at dt = 1/60 s with backward Euler stays stable, separates the body, and the CG
// iterations per step after the cut stay within twice those before.

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "blade_walks.hpp"
#include "incise/core/error.hpp"
#include "incise/engine/engine.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/solve/integrators.hpp"
#include "incise/xfem/visual_surface.hpp"
#include "incise/xfem/xfem_cutter.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

/// m: the widest gap between a vertex copy and its original.
double widest_opening(const Engine& engine) {
  double widest = 0.0;
  for (std::size_t v = 0; v < engine.mesh().vertex_count(); ++v) {
    const VertexOrigin& origin = engine.mesh().vertex_origin(static_cast<VertexId>(v));
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      widest =
          std::max(widest, (engine.positions()[v] - engine.positions()[origin.parents[0]]).norm());
    }
  }
  return widest;
}

TEST(XfemEngine, TheBlockUnderTensionOpensAlongTheCut) {
  Engine engine(
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "xfem_cut_pull.json"));
  ASSERT_NE(engine.xfem_cutter(), nullptr);
  EXPECT_EQ(engine.cutter(), nullptr);
  const double mass = engine.total_mass();
  const std::size_t tets = engine.mesh().tet_count();
  while (engine.frame() < 160) {
    ASSERT_TRUE(engine.step()) << engine.divergence();
    EXPECT_NEAR(engine.total_mass(), mass, 1e-12 * mass) << "frame " << engine.frame();
  }
  const ValidationReport report = validate(engine.mesh());
  EXPECT_TRUE(report.ok()) << report.describe();
  const XfemCutterStats& stats = engine.xfem_cutter()->stats();
  EXPECT_GT(stats.elements_split, 0u);
  // No element was subdivided: each split tetrahedron added exactly one element.
  EXPECT_EQ(engine.mesh().tet_count(), tets + stats.elements_split);
  const double widest = widest_opening(engine);
  std::printf(
      "XFEM block under a 4 mm pull: %zu tetrahedra split, %zu copies, lips part by %.2f mm\n",
      stats.elements_split, stats.copies, widest * 1e3);
  EXPECT_GT(widest, 0.5e-3);  // m: the lips part under the pull
  EXPECT_LT(widest, 1e-2);
  // The snapshot surface marks the faces the cut opened.
  EXPECT_FALSE(engine.cut_surface().empty());
}

TEST(XfemEngine, AFullCutOfEveryRealMeshIsStableAtASixtiethOfASecond) {
  int meshes = 0;
  for (const std::string& name : test::data_meshes()) {
    const auto path = test::data_file(name);
    if (!std::filesystem::exists(path)) {
      continue;
    }
    ++meshes;
    SCOPED_TRACE(name);
    const TetMesh mesh = read_tet_mesh(path).mesh;
    const auto [low, high] = bounding_box(mesh);
    const Vec3 size = high - low;
    const Vec3 margin = 0.05 * size;
    const double y = low.y() + 0.513 * size.y();
    // The full cut of issue "Cut real anatomy right", from frame 10 to 34; the low-x tenth of
    // the body is held, gravity pulls, backward Euler at 1/60 s with CG.
    const std::string scene_text = fmt::format(
        R"({{"mesh": {{"file": "{}"}}, "material": "liver",
            "model": {{"type": "corotational-fem", "rayleigh": [1.0, 0.01]}},
            "integrator": {{"type": "backward-euler", "dt": {},
                           "solver": {{"type": "cg", "preconditioner": "block-jacobi",
                                      "tolerance": 1e-6, "max_iterations": 2000}}}},
            "fixed": [{{"box": [[-1e9, -1e9, -1e9], [{}, 1e9, 1e9]]}}],
            "gravity": [0, 0, -9.81],
            "tool": {{"poses": [[{}, {}, {}, {}, {}, {}, {}], [{}, {}, {}, {}, {}, {}, {}]]}},
            "cutter": {{"type": "xfem"}},
            "frames": 60}})",
        path.string(), 1.0 / 60.0, low.x() + 0.1 * size.x(), 10.0 / 60.0, low.x() - margin.x(), y,
        low.z() - margin.z(), low.x() - margin.x(), y, high.z() + margin.z(), 34.0 / 60.0,
        high.x() + margin.x(), y, low.z() - margin.z(), high.x() + margin.x(), y,
        high.z() + margin.z());
    Engine engine(parse_scene(scene_text, "xfem-stability.json"));
    const int pieces_before = pieces_by_vertices(engine.mesh());
    std::size_t before = 0;  // the most CG iterations of a step before the blade arrives
    std::size_t after = 0;   // ... of a step once the body is cut through
    while (engine.frame() < 60) {
      ASSERT_TRUE(engine.step()) << engine.divergence();
      const std::size_t iterations = engine.integrator().stats().solver_iterations_last_step;
      (engine.frame() <= 10 ? before : after) =
          std::max(engine.frame() <= 10 ? before : after, iterations);
    }
    EXPECT_GT(pieces_by_vertices(engine.mesh()), pieces_before);
    EXPECT_LE(after, 2 * before) << "CG iterations per step before " << before << ", after "
                                 << after;
    std::printf("%s: %zu split, CG iterations per step at most %zu before the cut, %zu after\n",
                name.c_str(), engine.xfem_cutter()->stats().elements_split, before, after);
  }
  if (meshes == 0) {
    GTEST_SKIP() << "no data meshes";
  }
}

TEST(XfemEngine, TheSkinSceneCutsItsVisualSurfaceAndWritesIt) {
  const SceneDescription scene =
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "xfem_skin.json");
  Engine engine(scene);
  ASSERT_NE(engine.visual(), nullptr);
  const VisualSurface& visual = *engine.visual();
  EXPECT_TRUE(visual.original_closed());
  const double volume = enclosed_volume(visual.rest_points(), visual.triangles());
  const auto dir = test::scratch_dir("xfem-skin");
  VtuSeriesSink sink(dir, "skin", 20);
  engine.add_sink(sink);
  const RunResult result = run(engine, scene.frames);
  ASSERT_FALSE(result.diverged) << result.divergence;
  // The picture follows the cut: closed, the same volume at rest, faces on the cut, and the
  // lips of the visual surface part as the physics' do.
  EXPECT_TRUE(is_watertight(visual.triangles()));
  EXPECT_NEAR(enclosed_volume(visual.rest_points(), visual.triangles()), volume, 1e-6 * volume);
  EXPECT_EQ(visual.failures(), 0u);
  std::size_t cut_faces = 0;
  for (std::uint8_t on : visual.on_cut()) {
    cut_faces += on;
  }
  EXPECT_GT(cut_faces, 0u);
  const double widest = widest_opening(engine);
  EXPECT_GT(widest, 0.5e-3);  // m: the stretched skin gapes
  std::printf(
      "skin patch: %zu tetrahedra split, lips part by %.2f mm, visual surface %zu "
      "triangles (%zu on the cut)\n",
      engine.xfem_cutter()->stats().elements_split, widest * 1e3, visual.triangles().size(),
      cut_faces);
  EXPECT_TRUE(std::filesystem::exists(dir / "skin_visual.pvd"));
  EXPECT_TRUE(std::filesystem::exists(dir / fmt::format("skin_visual_{:06d}.vtp", scene.frames)));
  // A visual surface lives in rest tetrahedra the subdivision cutter would replace.
  std::string text = scene.source_text;
  text.replace(text.find("\"xfem\""), 6, "\"subdivision\"");
  EXPECT_THROW((void)parse_scene(text, scene.file), InputError);
}

TEST(XfemEngine, APushOnTheCollisionSurfaceMovesOnlyThePieceItLandsOn) {
  // A free 8 x 2 x 2 cm bar (no gravity, nothing held) cut through at x = 4.37 cm in the first
  // ten frames; its collision surface a box 2 mm inside. Then a push of 0.01 N upwards on a
  // collision triangle left of the cut, every frame: the left piece rises, the right one does
  // not move at all.
  const auto dir = test::scratch_dir("xfem-push");
  const TetMesh inner =
      make_box_grid({{19, 4, 4}, Vec3(0.076, 0.016, 0.016), Vec3(0.002, 0.002, 0.002), 6});
  std::vector<Triangle> faces;
  for (const BoundaryFace& face : boundary_faces(inner)) {
    faces.push_back(face.vertices);
  }
  write_obj(dir / "inner.obj", inner.rest_positions(), faces);
  const std::string text = R"({"mesh": {"box": {"cells": [8, 2, 2], "size": [0.08, 0.02, 0.02]}},
      "material": "liver", "model": {"type": "corotational-fem"},
      "integrator": {"type": "backward-euler", "dt": 0.01},
      "tool": {"poses": [[0.0, 0.0437, -0.01, -0.01, 0.0437, -0.01, 0.03],
                         [0.1, 0.0437, 0.03, -0.01, 0.0437, 0.03, 0.03]]},
      "cutter": {"type": "xfem"}, "collision": {"file": "inner.obj"}, "frames": 40})";
  Engine engine(parse_scene(text, dir / "push.json"));
  ASSERT_NE(engine.collision(), nullptr);
  EXPECT_EQ(engine.visual(), nullptr);
  while (engine.frame() < 12) {
    ASSERT_TRUE(engine.step()) << engine.divergence();
  }
  ASSERT_EQ(pieces_by_vertices(engine.mesh()), 2);
  const VisualSurface& surface = *engine.collision();
  std::size_t target = surface.triangles().size();
  for (std::size_t t = 0; t < surface.triangles().size() && target == surface.triangles().size();
       ++t) {
    Vec3 centre = Vec3::Zero();
    for (VertexId v : surface.triangles()[t]) {
      centre += surface.rest_points()[static_cast<std::size_t>(v)] / 3.0;
    }
    if (centre.x() < 0.02 && surface.on_cut()[t] == 0) {
      target = t;
    }
  }
  ASSERT_LT(target, surface.triangles().size());
  const std::vector<Vec3> before(engine.positions().begin(), engine.positions().end());
  for (int k = 0; k < 10; ++k) {
    engine.push(target, {1.0 / 3, 1.0 / 3, 1.0 / 3}, Vec3(0, 0, 0.01));
    ASSERT_TRUE(engine.step()) << engine.divergence();
  }
  double left_rise = 0.0;
  double right_motion = 0.0;
  for (std::size_t v = 0; v < before.size(); ++v) {
    const Vec3 moved = engine.positions()[v] - before[v];
    if (engine.mesh().rest_position(static_cast<VertexId>(v)).x() < 0.03) {
      left_rise = std::max(left_rise, moved.z());
    } else if (engine.mesh().rest_position(static_cast<VertexId>(v)).x() > 0.05) {
      right_motion = std::max(right_motion, moved.norm());
    }
  }
  EXPECT_GT(left_rise, 1e-4);  // m: the pushed piece rises
  // The other is not pushed: it moves by rounding only (the solver's start from earlier steps).
  EXPECT_LT(right_motion, 1e-6 * left_rise);
  std::printf("push on the left piece: it rises %.3g m, the right piece moves %.3g m\n", left_rise,
              right_motion);
  EXPECT_THROW(engine.push(surface.triangles().size(), {1, 0, 0}, Vec3::UnitZ()), InputError);
}

TEST(XfemEngine, XfemNeedsTheFiniteElementModel) {
  const std::string text = R"({"mesh": {"box": {"cells": [2, 2, 2], "size": [0.02, 0.02, 0.02]}},
      "model": {"type": "mass-spring"}, "cutter": {"type": "xfem"}})";
  try {
    (void)parse_scene(text, "springs.json");
    FAIL() << "xfem with springs was accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("cutter.type"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("corotational-fem"), std::string::npos)
        << error.what();
  }
  const std::string wrong_key =
      R"({"mesh": {"box": {"cells": [2, 2, 2], "size": [0.02, 0.02, 0.02]}},
      "model": {"type": "corotational-fem"}, "cutter": {"type": "xfem", "snap_fraction": 0.2}})";
  EXPECT_THROW((void)parse_scene(wrong_key, "snap.json"), InputError);
}

}  // namespace
}  // namespace incise
