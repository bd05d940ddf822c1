// What a cutting frame costs against a frame that does not cut, at three body sizes (the issue
// "An engine you can step and cut at any size"): the peers' FEM box (0.1 m, n^3 cells, 6 tets
// per cell, E = 3 kPa, nu = 0.45, rho = 1000 kg/m^3, z = 0 face held, gravity), backward
// Euler dt = 0.01 s with block-Jacobi CG to 1e-6, a vertical blade entering at x = 0.05 m,
// reaching 3 cm deep at 1 mm per frame. A cut costs what it cuts when the extra time of a
// cutting frame does not grow with the body. Frames are compared with those after the cut
// (the same cut body, the blade at rest): the body's motion after a cut, not the edit, is what
// raises CG iterations over the uncut body's frames, listed too.
//
// usage: cut_cost_bench [--cells 10,20,40] [--model corotational-fem|mass-spring]
//                       [--cutter subdivision|xfem] [--blade-x 0.05] [--per-frame 1]
//                       [--preconditioner block-jacobi|two-level] [--paired-every 3]
//                       [--products single|double] [--tolerance 1e-6] [--threads N]
// --threads N: the engine's worker threads (default: every core the process may use).
// --paired-every K (0: off): every K-th cutting frame is also stepped from the same state with
// the blade held still (the engine resumed from a checkpoint taken just before it), so the cut's
// own extra is measured without the body's motion, which differs from frame to frame.
// (x = 0.05 m is a plane of grid vertices at every n here; 0.0537 m crosses the cells)
// Frames 1-10 are "before", 16-45 (the blade moving inside) "cutting", 46-65 "after".

#include <fmt/format.h>
#include <tbb/global_control.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "incise/engine/engine.hpp"
#include "incise/engine/tool_pose_source.hpp"
#include "incise/solve/integrators.hpp"

namespace {

using incise::Engine;
using incise::FrameRecord;

struct Means {
  double cd = 0, gc = 0, rx = 0, total = 0, iterations = 0;
  double refresh = 0, forces = 0, preconditioner = 0, solve = 0;  // s, within rx
  int frames = 0;
  void add(const FrameRecord& r, const incise::IntegratorStats& stats) {
    iterations += static_cast<double>(stats.solver_iterations_last_step);
    refresh += stats.seconds_refresh;
    forces += stats.seconds_forces;
    preconditioner += stats.seconds_preconditioner;
    solve += stats.seconds_products + stats.seconds_vector_updates + stats.seconds_solver_start;
    cd += r.cd;
    gc += r.gc;
    rx += r.rx;
    total += r.cd + r.gc + r.rx;
    ++frames;
  }
  [[nodiscard]] std::string row() const {
    const double n = frames > 0 ? frames : 1;
    return fmt::format("{:.1f} ({:.1f} / {:.1f} / {:.1f}; {:.0f} CG)", 1e3 * total / n,
                       1e3 * cd / n, 1e3 * gc / n, 1e3 * rx / n, iterations / n);
  }
  [[nodiscard]] double mean() const { return frames > 0 ? total / frames : 0.0; }
  [[nodiscard]] double per_frame(double sum) const { return frames > 0 ? sum / frames : 0.0; }
  /// Solver time per CG iteration (s).
  [[nodiscard]] double per_iteration() const { return iterations > 0 ? solve / iterations : 0.0; }
};

std::string scene_text(int cells, const std::string& model, const std::string& cutter, double x,
                       const std::string& preconditioner, const std::string& products,
                       double tolerance) {
  // Frames 1-10: the blade waits outside (y < 0); 11-45: it moves 1 mm per frame to 3 cm deep
  // (5 mm of approach first); 46-65: it rests inside.
  return fmt::format(R"({{
    "mesh": {{"box": {{"cells": [{0}, {0}, {0}], "size": [0.1, 0.1, 0.1], "tets_per_cell": 6}}}},
    "material": {{"young_modulus": 3000, "poisson_ratio": 0.45, "density": 1000}},
    "model": {{"type": "{1}"}},
    "integrator": {{"type": "backward-euler", "dt": 0.01,
                    "solver": {{"type": "cg", "preconditioner": "{4}", "tolerance": {6},
                                "products": "{5}"}}}},
    "fixed": [{{"box": [[-1, -1, -1], [1, 1, 0]]}}],
    "gravity": [0, 0, -9.81],
    "tool": {{"poses": [[0.0, {3}, -0.005, -0.01, {3}, -0.005, 0.11],
                        [0.10, {3}, -0.005, -0.01, {3}, -0.005, 0.11],
                        [0.45, {3}, 0.030, -0.01, {3}, 0.030, 0.11]]}},
    "cutter": {{"type": "{2}"}},
    "frames": 65, "frame_dt": 0.01}})",
                     cells, model, cutter, x, preconditioner, products, tolerance);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes{10, 20, 40};
  std::string model = "corotational-fem";
  std::string cutter = "subdivision";
  double blade_x = 0.05;  // m
  std::string preconditioner = "block-jacobi";
  std::string products = "single";  // CG's matrix copy (the default), or "double"
  bool per_frame = false;           // --per-frame 1: every frame on stderr
  int paired_every = 3;
  double tolerance = 1e-6;  // CG's relative residual (1e-3: the viewer's real-time bodies)
  std::unique_ptr<tbb::global_control> threads;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--cells") == 0) {
      sizes = incise::bench::comma_separated_ints(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--model") == 0) {
      model = argv[i + 1];
    } else if (std::strcmp(argv[i], "--cutter") == 0) {
      cutter = argv[i + 1];
    } else if (std::strcmp(argv[i], "--blade-x") == 0) {
      blade_x = std::atof(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--preconditioner") == 0) {
      preconditioner = argv[i + 1];
    } else if (std::strcmp(argv[i], "--products") == 0) {
      products = argv[i + 1];
    } else if (std::strcmp(argv[i], "--tolerance") == 0) {
      tolerance = std::atof(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--paired-every") == 0) {
      paired_every = std::atoi(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--per-frame") == 0) {
      per_frame = std::strcmp(argv[i + 1], "0") != 0;
    } else if (std::strcmp(argv[i], "--threads") == 0) {
      threads = incise::bench::thread_limit(argv[i + 1]);
    }
  }
  std::printf(
      "| n | tets | cutting frame ms (cd / gc / rx; CG iterations) | frames before the cut | "
      "frames after the cut | extra ms over after | ratio to after |\n"
      "|---|---|---|---|---|---|---|\n");
  std::vector<std::string> where;   // the second table's rows
  std::vector<std::string> paired;  // the third's
  const std::filesystem::path checkpoint =
      std::filesystem::temp_directory_path() / "cut_cost_bench.checkpoint";
  for (int n : sizes) {
    Engine engine(incise::parse_scene(
        scene_text(n, model, cutter, blade_x, preconditioner, products, tolerance),
        "cut_cost.json"));
    const std::size_t tets = engine.mesh().tet_count();
    Means cutting;
    Means before;  // the whole body, not cut yet
    Means after;   // the cut body, the blade at rest in it
    // The body's motion, not the edit, sets the CG iterations (they climb through the cut and
    // fall back after it): the last cutting frames and the first after the cut find the body
    // in nearly the same state.
    Means last_cutting;  // frames 41-45
    Means first_after;   // frames 46-50
    std::size_t tets_before_cut = 0;
    std::size_t tets_after_cut = 0;
    Means pair_cut;   // the sampled cutting frames
    Means pair_held;  // the same frames from the same state, the blade held still
    for (int frame = 0; frame < 65; ++frame) {
      const int next = engine.frame() + 1;
      const bool pair =
          paired_every > 0 && next >= 16 && next <= 45 && (next - 16) % paired_every == 0;
      std::unique_ptr<Engine> held;
      if (pair && engine.blade_rest()) {
        engine.save_checkpoint(checkpoint);
        held = Engine::resume(checkpoint);
        held->set_tool_source(std::make_unique<incise::ScriptedToolPath>(
            std::vector<incise::BladePose>{*engine.blade_rest()}));
      }
      if (!engine.step()) {
        std::fprintf(stderr, "%s\n", engine.divergence().c_str());
        return 1;
      }
      const FrameRecord& r = engine.last_frame();
      const incise::IntegratorStats& stats = engine.integrator().stats();
      if (per_frame) {
        std::fprintf(stderr,
                     "n %d frame %d tets %zu cd %.2f gc %.2f update %.2f rx %.2f CG %zu "
                     "(forces %.2f preconditioner %.2f start %.2f products %.2f updates %.2f)\n",
                     n, r.frame, r.tets, 1e3 * r.cd, 1e3 * r.gc, 1e3 * stats.seconds_refresh,
                     1e3 * r.rx, stats.solver_iterations_last_step, 1e3 * stats.seconds_forces,
                     1e3 * stats.seconds_preconditioner, 1e3 * stats.seconds_solver_start,
                     1e3 * stats.seconds_products, 1e3 * stats.seconds_vector_updates);
      }
      if (held) {
        if (!held->step()) {
          std::fprintf(stderr, "%s\n", held->divergence().c_str());
          return 1;
        }
        pair_cut.add(r, stats);
        pair_held.add(held->last_frame(), held->integrator().stats());
      }
      if (r.frame == 15) {
        tets_before_cut = r.tets;
      } else if (r.frame == 45) {
        tets_after_cut = r.tets;
      }
      if (r.frame >= 41 && r.frame <= 45) {
        last_cutting.add(r, stats);
      } else if (r.frame >= 46 && r.frame <= 50) {
        first_after.add(r, stats);
      }
      if (r.frame <= 10) {
        before.add(r, stats);
      } else if (r.frame >= 16 && r.frame <= 45) {
        cutting.add(r, stats);
      } else if (r.frame >= 46) {
        after.add(r, stats);
      }
    }
    std::printf("| %d | %zu -> %zu | %s | %s | %s | %.1f | %.2f |\n", n, tets,
                engine.mesh().tet_count(), cutting.row().c_str(), before.row().c_str(),
                after.row().c_str(), 1e3 * (cutting.mean() - after.mean()),
                after.mean() > 0 ? cutting.mean() / after.mean() : 0.0);
    std::fflush(stdout);
    const auto ms = [](double seconds) { return 1e3 * seconds; };
    const double edit = cutting.per_frame(cutting.cd + cutting.gc + cutting.refresh);
    const double extra_iterations =
        cutting.per_frame(cutting.iterations) - after.per_frame(after.iterations);
    const double new_tets = static_cast<double>(tets_after_cut - tets_before_cut) / 30.0;
    where.push_back(fmt::format(
        "| {} | {:.1f} ({:.1f} / {:.1f} / {:.1f}) | {:.0f} / {:.3f} | {:.1f} x {:.3f} = {:.1f} | "
        "{:.3f} | {:.1f} | {:.1f} | {:.1f} ({:.0f} CG) / {:.1f} ({:.0f} CG) = {:.2f} |",
        n, ms(edit), ms(cutting.per_frame(cutting.cd)), ms(cutting.per_frame(cutting.gc)),
        ms(cutting.per_frame(cutting.refresh)), new_tets, new_tets > 0 ? ms(edit) / new_tets : 0.0,
        extra_iterations, ms(after.per_iteration()), ms(extra_iterations * after.per_iteration()),
        ms(cutting.per_iteration()),
        ms(cutting.per_frame(cutting.forces + cutting.preconditioner) -
           after.per_frame(after.forces + after.preconditioner)),
        ms(cutting.mean() - after.mean()), ms(last_cutting.mean()),
        last_cutting.per_frame(last_cutting.iterations), ms(first_after.mean()),
        first_after.per_frame(first_after.iterations),
        first_after.mean() > 0 ? last_cutting.mean() / first_after.mean() : 0.0));
    if (pair_cut.frames > 0) {
      // The cut's own extra: its edit, the CG iterations it adds over the same frame with the
      // blade held (each at the cutting frames' cost), and the forces and preconditioner set-up
      // of the tetrahedra it added, taken against the frames after the cut (the held engine's
      // first step after resuming allocates and builds from nothing, which would hide them).
      // The CG comparison is exact for block-Jacobi; the two-level one's resumed coarse space is
      // aggregated afresh, not extended, so it may need a few iterations more or less.
      const double edit_ms = ms(pair_cut.per_frame(pair_cut.cd + pair_cut.gc + pair_cut.refresh));
      const double more_iterations =
          pair_cut.per_frame(pair_cut.iterations) - pair_held.per_frame(pair_held.iterations);
      const double iteration_ms = more_iterations * ms(pair_cut.per_iteration());
      const double other_ms = ms(cutting.per_frame(cutting.forces + cutting.preconditioner) -
                                 after.per_frame(after.forces + after.preconditioner));
      const double extra_ms = edit_ms + iteration_ms + other_ms;
      paired.push_back(fmt::format(
          "| {} | {} | {:.1f} | {:.1f} / {:.1f} CG: {:+.1f} x {:.3f} = {:.1f} | {:.1f} | {:.1f} | "
          "{:.2f} |",
          n, pair_cut.frames, edit_ms, pair_cut.per_frame(pair_cut.iterations),
          pair_held.per_frame(pair_held.iterations), more_iterations, ms(pair_cut.per_iteration()),
          iteration_ms, other_ms, extra_ms,
          pair_cut.mean() > 0 ? 1e3 * pair_cut.mean() / (1e3 * pair_cut.mean() - extra_ms) : 0.0));
    }
  }
  std::filesystem::remove(checkpoint);
  if (!paired.empty()) {
    std::printf(
        "\nThe cut's own extra, from the same state (every %d-th cutting frame stepped twice: "
        "as it cuts, and resumed from a checkpoint with the blade held): the edit (cd + gc + "
        "model update), CG iterations cutting / held and the extra at the cutting frames' ms "
        "per iteration, forces + preconditioner extra, all of it (ms), and the cutting frame "
        "over the same frame without its extra\n\n"
        "| n | frames | edit | CG iterations | forces + preconditioner | extra | ratio |\n"
        "|---|---|---|---|---|---|---|\n",
        paired_every);
    for (const std::string& row : paired) {
      std::printf("%s\n", row.c_str());
    }
  }
  std::printf(
      "\nWhere the extra of a cutting frame goes (ms per frame): the edit (cd / gc / the model "
      "following it), the tetrahedra it adds and its cost per added tetrahedron, extra CG "
      "iterations at the after-frames' cost per iteration, the cutting frames' cost per "
      "iteration, forces + preconditioner over the after-frames', all of it; and the last five "
      "cutting frames against the first five after the cut (the body in nearly the same "
      "state)\n\n"
      "| n | edit (cd / gc / model update) | tets added per frame / edit ms per tet | extra CG "
      "iterations x ms each | ms per iteration when cutting | forces + preconditioner extra | "
      "extra in all | frames 41-45 / 46-50 ms |\n"
      "|---|---|---|---|---|---|---|---|\n");
  for (const std::string& row : where) {
    std::printf("%s\n", row.c_str());
  }
  return 0;
}
