// Cutting: the seed's Table 1 setting (straight full cuts through 2x2x2, 2x4x3 and 4x6x4-cell
// grids of 6 tets per cell) and the cost of collision detection (cd) and topology changes (gc)
// per frame for the same blade path on meshes from 6k to 500k tetrahedra.
// Run: build/release/bench/cut_bench   (results in BENCHMARKS.md)

#include <chrono>
#include <cstdio>

#include "incise/core/timing.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"

using namespace incise;

namespace {

/// A vertical blade (tip below the block, base above) swept along y at x = 0.6 of the width (off
/// the grid planes), in `poses` steps from outside to outside.
std::vector<BladePose> straight_cut(const Vec3& size, int poses) {
  std::vector<BladePose> path;
  for (int i = 0; i <= poses; ++i) {
    const double y = -0.1 * size.y() + 1.2 * size.y() * i / poses;
    path.push_back({0.01 * i, Vec3(0.6 * size.x(), y, -0.2 * size.z()),
                    Vec3(0.6 * size.x(), y, 1.2 * size.z())});
  }
  return path;
}

}  // namespace

int main() {
  std::printf("Seed Table 1 setting: straight full cuts, 6 tets per cell, 24 poses\n");
  std::printf("%-10s %-8s %8s %9s %11s %9s %8s %9s %9s\n", "cells", "split", "tets in", "tets out",
              "seed 1:17", "cut cm^2", "tets/cm", "cd ms/fr", "gc ms/fr");
  const std::array<std::array<int, 3>, 3> grids = {{{2, 2, 2}, {2, 4, 3}, {4, 6, 4}}};
  const int seed_counts[3] = {354, 960, 2446};
  for (int g = 0; g < 3; ++g) {
    // Minimal splits opening under the blade (the default), the same opening face by face
    // (no vertices on the blade line), and the seed's generic split.
    for (int variant = 0; variant < 3; ++variant) {
      const SplitMode split = variant == 2 ? SplitMode::kGeneric : SplitMode::kMinimal;
      BoxGridOptions options;
      options.cells = grids[g];
      options.size =
          Vec3(0.01 * grids[g][0], 0.01 * grids[g][1], 0.01 * grids[g][2]);  // 1 cm cells
      TetMesh mesh = make_box_grid(options);
      const std::size_t before = mesh.tet_count();
      CutterOptions cutter_options;
      cutter_options.split = split;
      cutter_options.open_under_blade = variant != 1;
      SubdivisionCutter cutter(mesh, cutter_options);
      const auto path = straight_cut(options.size, 24);
      cutter.cut_along(path);
      const CutStats& stats = cutter.stats();
      const double length_cm = 100.0 * options.size.y();
      std::printf("%-10s %-8s %8zu %9zu %11d %9.2f %8.1f %9.3f %9.3f  valid=%d watertight=%d\n",
                  (std::to_string(grids[g][0]) + "x" + std::to_string(grids[g][1]) + "x" +
                   std::to_string(grids[g][2]))
                      .c_str(),
                  variant == 0 ? "minimal" : (variant == 1 ? "by-face" : "generic"), before,
                  mesh.tet_count(), seed_counts[g], 1e4 * stats.cut_area,
                  static_cast<double>(mesh.tet_count() - before) / length_cm,
                  1e3 * stats.total_cd_seconds / 24, 1e3 * stats.total_gc_seconds / 24,
                  validate(mesh).ok() ? 1 : 0, check_boundary(mesh).watertight() ? 1 : 0);
    }
  }

  std::printf(
      "\nLocality: a 2 cm incision (2 cm deep) with 1 mm steps into a 10 cm cube of n^3 cells\n");
  std::printf("%-6s %10s %12s %14s %14s %16s\n", "n", "tets", "cut tets/fr", "cd ms/frame",
              "gc ms/frame", "(cd+gc) us/tet");
  for (int n : {10, 20, 30, 46, 64}) {
    BoxGridOptions options;
    options.cells = {n, n, n};
    options.size = Vec3(0.1, 0.1, 0.1);
    const auto setup_start = Clock::now();
    TetMesh mesh = make_box_grid(options);
    SubdivisionCutter cutter(mesh);
    const double setup = seconds_since(setup_start);
    std::vector<BladePose> path;
    for (int i = 0; i <= 20; ++i) {
      const double y = 0.04 + 0.001 * i;
      path.push_back({0.01 * i, Vec3(0.0537, y, 0.08), Vec3(0.0537, y, 0.12)});
    }
    const std::size_t before = mesh.tet_count();
    cutter.cut_along(path);
    const CutStats& stats = cutter.stats();
    const double frames = 20.0;
    const double cut_tets = static_cast<double>(mesh.tet_count() - before) / frames;
    std::printf(
        "%-6d %10zu %12.1f %14.3f %14.3f %16.2f   (setup %.0f ms)\n", n, before, cut_tets,
        1e3 * stats.total_cd_seconds / frames, 1e3 * stats.total_gc_seconds / frames,
        1e6 * (stats.total_cd_seconds + stats.total_gc_seconds) / frames / std::max(1.0, cut_tets),
        1e3 * setup);
  }
  return 0;
}
