// Bodies of several materials: a material table with a material per tetrahedron, chosen by
// region (box or file label) in the scene, used by both models; labels follow cuts.

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/engine/engine.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

constexpr double kLength = 0.1;    // m, along x
constexpr double kWidth = 0.01;    // m
constexpr double kDensity = 1000;  // kg/m^3
constexpr double kGravity = 9.81;  // m/s^2, along +x: the bar hangs from its x = 0 end
constexpr double kStiff = 1e5;     // Pa, the held half
constexpr double kSoft = 2.5e4;    // Pa, the free half

std::string bar_scene(int cells_along, const std::string& model, const std::string& integrator) {
  return fmt::format(R"({{
    "mesh": {{"box": {{"cells": [{}, 1, 1], "size": [{}, {}, {}]}}}},
    "material": {{"young_modulus": {}, "poisson_ratio": 0.0, "density": {}}},
    "materials": [{{"material": {{"young_modulus": {}, "poisson_ratio": 0.0, "density": {}}},
                    "region": {{"box": [[-1, -1, -1], [{}, 1, 1]]}}}}],
    "model": {{"type": "{}"}},
    "integrator": {{"type": "{}", "dt": 0.01}},
    "fixed": [{{"box": [[-1, -1, -1], [0, 1, 1]]}}],
    "gravity": [{}, 0, 0], "frames": 1, "frame_dt": 0.01}})",
                     cells_along, kLength, kWidth, kWidth, kSoft, kDensity, kStiff, kDensity,
                     kLength / 2, model, integrator, kGravity);
}

/// Mean x-displacement (m) of the vertices at the free end after one static frame.
double tip_displacement(int cells_along) {
  Engine engine(parse_scene(bar_scene(cells_along, "corotational-fem", "static"), "bar.json"));
  EXPECT_TRUE(engine.step()) << engine.divergence();
  double sum = 0.0;
  int count = 0;
  for (std::size_t v = 0; v < engine.mesh().vertex_count(); ++v) {
    const Vec3& rest = engine.mesh().rest_position(static_cast<VertexId>(v));
    if (std::abs(rest.x() - kLength) < 1e-12) {
      sum += engine.positions()[v].x() - rest.x();
      ++count;
    }
  }
  return sum / count;
}

TEST(Materials, TwoMaterialBarMatchesTheExactSeriesSolution) {
  // nu = 0: a uniaxial state. Stress at x is rho g (L - x); integrating strain over the stiff
  // half and the soft half gives u(L) = rho g (3 L^2 / (8 E1) + L^2 / (8 E2)).
  const double exact = kDensity * kGravity *
                       (3 * kLength * kLength / (8 * kStiff) + kLength * kLength / (8 * kSoft));
  double previous_error = 1.0;
  for (int cells : {4, 8, 16}) {
    const double error = std::abs(tip_displacement(cells) - exact) / exact;
    std::printf("two-material bar, %d cells along: tip %.6g m, exact %.6g m, error %.3g %%\n",
                cells, tip_displacement(cells), exact, 100 * error);
    EXPECT_LE(error, previous_error + 1e-9) << cells << " cells";
    previous_error = error;
  }
  EXPECT_LT(previous_error, 0.01);
  // One material everywhere (the soft one) would hang much further: the table is used.
  EXPECT_GT(kDensity * kGravity * kLength * kLength / (2 * kSoft), 1.5 * exact);
}

TEST(Materials, BothModelsTakeEachTetrahedronsDensity) {
  for (const char* model : {"mass-spring", "corotational-fem"}) {
    std::string text = bar_scene(4, model, "backward-euler");
    // Twice as dense in the held half.
    const std::string stiff = fmt::format(
        R"("young_modulus": {}, "poisson_ratio": 0.0, "density": {})", kStiff, kDensity);
    text.replace(text.find(stiff), stiff.size(),
                 fmt::format(R"("young_modulus": {}, "poisson_ratio": 0.0, "density": {})", kStiff,
                             2 * kDensity));
    Engine engine(parse_scene(text, "dense.json"));
    const double volume = kLength * kWidth * kWidth;
    EXPECT_NEAR(engine.total_mass(), 1.5 * kDensity * volume, 1e-12) << model;
  }
}

TEST(Materials, ARegionThatSelectsNothingIsAnError) {
  std::string text = bar_scene(4, "mass-spring", "backward-euler");
  const std::string region = "[[-1, -1, -1], [0.05, 1, 1]]";
  ASSERT_NE(text.find(region), std::string::npos);
  text.replace(text.find(region), region.size(), "[[5, 5, 5], [6, 6, 6]]");
  try {
    Engine engine(parse_scene(text, "empty.json"));
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("materials[0] selects no tetrahedron"),
              std::string::npos)
        << error.what();
  }
}

TEST(Materials, TheExampleSceneShowsEachMaterialInItsFrames) {
  // skin_over_fat.json: the top centimetre skin, the rest fat; the frames carry a "material"
  // cell array (read back as the file's region labels), cut tetrahedra keeping theirs.
  Engine engine(
      load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "skin_over_fat.json"));
  ASSERT_NE(engine.materials(), nullptr);
  ASSERT_EQ(engine.materials()->table().size(), 2u);
  const auto dir = test::scratch_dir("skin-over-fat");
  VtuSeriesSink series(dir, "frame", 40, 60);
  engine.add_sink(series);
  (void)run(engine, 60);
  ASSERT_GT(engine.mesh().tet_count(), 576u);  // the scalpel is in
  const TetMesh frame = read_tet_mesh(dir / "frame_000060.vtu").mesh;
  ASSERT_EQ(frame.tet_count(), engine.mesh().tet_count());
  double skin = 0.0;
  for (std::size_t t = 0; t < frame.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    EXPECT_EQ(frame.tet_label(tet), engine.materials()->id(tet));
    if (frame.tet_label(tet) == 1) {
      skin += signed_volume(engine.mesh(), tet);  // at rest (the frame holds positions)
      // The engine's own corners: a reader drops points no tetrahedron uses (vertices a cut
      // collapsed), so the frame's vertex numbers may differ from the engine's.
      double z = 0.0;
      for (VertexId v : engine.mesh().tet(tet)) {
        z += 0.25 * engine.mesh().rest_position(v).z();
      }
      EXPECT_GE(z, 0.03 - 1e-12);  // skin stays where the scene put it, through the cut
    }
  }
  EXPECT_NEAR(skin, 0.04 * 0.06 * 0.01, 1e-12);  // m^3: the top centimetre, cut or not
}

TEST(Materials, RegionLabelsSurviveReadCutWriteRead) {
  // A labelled grid (left half 2, right half 5) cut across both halves: children keep their
  // parent's label, so each region keeps its volume exactly, in every format read back.
  BoxGridOptions options;
  options.cells = {4, 3, 3};
  options.size = Vec3(0.04, 0.03, 0.03);
  const TetMesh grid = make_box_grid(options);
  std::vector<int> labels;
  for (std::size_t t = 0; t < grid.tet_count(); ++t) {
    double x = 0.0;
    for (VertexId v : grid.tet(static_cast<TetId>(t))) {
      x += 0.25 * grid.rest_position(v).x();
    }
    labels.push_back(x < 0.02 ? 2 : 5);
  }
  const auto dir = test::scratch_dir("labels-cut");
  {
    const TetMesh labelled(
        std::vector<Vec3>(grid.rest_positions().begin(), grid.rest_positions().end()),
        std::vector<Tet>(grid.tets().begin(), grid.tets().end()), labels);
    write_tet_mesh(dir / "in.vtu", labelled);
  }
  TetMesh mesh = read_tet_mesh(dir / "in.vtu").mesh;
  const auto volumes = [](const TetMesh& m) {
    std::map<int, double> result;
    for (std::size_t t = 0; t < m.tet_count(); ++t) {
      result[m.tet_label(static_cast<TetId>(t))] += signed_volume(m, static_cast<TetId>(t));
    }
    return result;
  };
  const std::map<int, double> before = volumes(mesh);
  ASSERT_EQ(before.size(), 2u);
  const std::size_t tets_in = mesh.tet_count();
  {
    SubdivisionCutter cutter(mesh);
    cutter.cut_along({{0.0, Vec3(-0.01, 0.0137, -0.01), Vec3(-0.01, 0.0137, 0.05)},
                      {1.0, Vec3(0.05, 0.0137, -0.01), Vec3(0.05, 0.0137, 0.05)}});
  }
  ASSERT_GT(mesh.tet_count(), tets_in);
  ASSERT_TRUE(validate(mesh).ok());
  for (const char* extension : {".vtu", ".msh", ".mesh", ".node"}) {
    const auto path = dir / (std::string("cut") + extension);
    write_tet_mesh(path, mesh);
    const std::map<int, double> after = volumes(read_tet_mesh(path).mesh);
    ASSERT_EQ(after.size(), 2u) << extension;
    for (const auto& [label, volume] : before) {
      EXPECT_NEAR(after.at(label), volume, 1e-9 * volume) << extension << " label " << label;
    }
  }
}

}  // namespace
}  // namespace incise
