// How far XFEM's physics trails the blade (the XFEM paper's Fig. 12): semi-progressive cutting
// splits a tetrahedron only once the blade has crossed it completely, so the physics waits from
// the move that first reaches a tetrahedron to the one that splits it. Measured against blade
// speed and mesh size: a vertical blade crosses the 0.1 m box (n^3 cells, 6 tetrahedra each) at
// x = 0.0537 m, poses at 60 Hz, the cutter alone (no physics).
//
// usage: xfem_delay_bench [--cells 10,20,40] [--speeds 0.03,0.06,0.12,0.24]   (m/s)

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/xfem/xfem_cutter.hpp"

int main(int argc, char** argv) {
  std::vector<double> cells{10, 20, 40};
  std::vector<double> speeds{0.03, 0.06, 0.12, 0.24};  // m/s
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--cells") == 0) {
      cells = incise::bench::comma_separated(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--speeds") == 0) {
      speeds = incise::bench::comma_separated(argv[i + 1]);
    }
  }
  std::printf(
      "| n | cell mm | blade speed mm/s | mm per frame | splits | mean delay ms | max delay ms | "
      "mean delay mm | max delay mm |\n|---|---|---|---|---|---|---|---|---|\n");
  constexpr double kFrame = 1.0 / 60.0;  // s
  for (double n : cells) {
    for (double speed : speeds) {
      const int count = static_cast<int>(n);
      incise::TetMesh mesh = incise::make_box_grid(
          {{count, count, count}, incise::Vec3(0.1, 0.1, 0.1), incise::Vec3::Zero(), 6});
      incise::XfemCutter cutter(mesh);
      const double x = 0.0537;
      const auto pose = [&](double t) {
        const double y = -0.005 + speed * t;
        return incise::BladePose{t, incise::Vec3(x, y, -0.01), incise::Vec3(x, y, 0.11)};
      };
      cutter.start(pose(0.0));
      for (int frame = 1; - 0.005 + speed * frame * kFrame < 0.105; ++frame) {
        cutter.move_to(pose(frame * kFrame));
      }
      const incise::XfemCutterStats& stats = cutter.stats();
      const double splits = static_cast<double>(stats.elements_split);
      std::printf("| %d | %.1f | %.0f | %.2f | %zu | %.1f | %.1f | %.2f | %.2f |\n", count,
                  100.0 / n, 1e3 * speed, 1e3 * speed * kFrame, stats.elements_split,
                  1e3 * stats.delay_sum / splits, 1e3 * stats.delay_max,
                  1e3 * stats.delay_travel_sum / splits, 1e3 * stats.delay_travel_max);
      std::fflush(stdout);
    }
  }
  return 0;
}
