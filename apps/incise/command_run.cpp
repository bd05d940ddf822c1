// incise run [SCENE] [--frames N] [--out DIR] [--report FILE] [--threads N] [--tool CSV]
// [--record-tool CSV] [--render DIR [--render-every N] [--size WxH] [--mode faces|wire|cut]
// [--video FILE.mp4]]: runs a scene headless, a short loop over the engine.

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <tuple>

#include "command_options.hpp"
#include "commands.hpp"
#include "incise/batch/visual_report.hpp"
#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/engine/engine.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/solve/integrators.hpp"
#include "incise/view/render_sink.hpp"
#include "incise/view/session_recording.hpp"
#ifdef INCISE_HAVE_GL
#include "incise/render/offscreen.hpp"
#endif

namespace incise::app {
namespace {

/// A frame's relaxation parts in ms, for the report.
nlohmann::ordered_json rx_parts_ms(const FrameRecord::RelaxationParts& parts) {
  return {{"refresh", 1e3 * parts.refresh},
          {"forces", 1e3 * parts.forces},
          {"preconditioner", 1e3 * parts.preconditioner},
          {"start", 1e3 * parts.start},
          {"products", 1e3 * parts.products},
          {"vector_updates", 1e3 * parts.vector_updates}};
}

/// A progress bar on a terminal, a plain line per 10 % otherwise (logs, CI).
class Progress {
 public:
  /// Frames first+1 .. last (global numbers: a resumed run starts past 0).
  Progress(int first, int last)
      : first_(first), last_(last), terminal_(isatty(fileno(stderr)) != 0) {}
  void update(const FrameRecord& record, double elapsed) {
    const int done = record.frame - first_;
    const int total = last_ - first_;
    const double fps = elapsed > 0.0 ? done / elapsed : 0.0;
    if (terminal_) {
      const int width = 30;
      const int filled = total > 0 ? width * done / total : width;
      std::cerr << fmt::format("\r[{}{}] {}/{} frames  t = {:.3f} s  {:.1f} frames/s ",
                               std::string(static_cast<std::size_t>(filled), '#'),
                               std::string(static_cast<std::size_t>(width - filled), '.'),
                               record.frame, last_, record.time, fps)
                << std::flush;
      if (record.frame == last_) {
        std::cerr << "\n";
      }
    } else if (total > 0 && (done * 10 / total != (done - 1) * 10 / total)) {
      std::cerr << fmt::format(
          "frame {}/{}  t = {:.3f} s  {:.1f} frames/s  max displacement {:.4g} m\n", record.frame,
          last_, record.time, fps, record.max_displacement);
    }
  }
  void interrupt() const {
    if (terminal_) {
      std::cerr << "\n";
    }
  }

 private:
  int first_;
  int last_;
  bool terminal_;
};

/// Pictures of the run, when asked for: the offscreen renderer and its sink.
struct Pictures {
  std::unique_ptr<ImageRenderer> renderer;
  std::optional<RenderSink> sink;
};

}  // namespace

Runner add_run_command(CLI::App& app) {
  auto* command = app.add_subcommand(
      "run", "Run a scene headless and write a ParaView series (no scene: the default one)");
  auto scene_path = std::make_shared<std::string>();
  auto frames = std::make_shared<int>(-1);
  auto out = std::make_shared<std::string>();
  auto report_path = std::make_shared<std::string>();
  command->add_option("scene", *scene_path, "Scene file (JSON); see scenes/README.md")
      ->check(CLI::ExistingFile);
  command->add_option("--frames", *frames, "Number of frames (overrides the scene)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--out", *out, "Output folder (overrides the scene's output.dir)");
  command->add_option("--report", *report_path, "Write a JSON report of per-stage timings here");
  auto tool_path = std::make_shared<std::string>();
  command
      ->add_option("--tool", *tool_path,
                   "Blade path CSV (t,tip_x,tip_y,tip_z,base_x,base_y,base_z; s, m) replacing the "
                   "scene's tool path, e.g. one recorded with --record-tool")
      ->check(CLI::ExistingFile);
  auto record_path = std::make_shared<std::string>();
  command->add_option("--record-tool", *record_path,
                      "Write the blade pose of every frame to this CSV (replay with --tool)");
  auto checkpoint = std::make_shared<std::string>();
  auto checkpoint_every = std::make_shared<int>(0);
  auto resume_path = std::make_shared<std::string>();
  auto* checkpoint_option =
      command->add_option("--checkpoint", *checkpoint,
                          "Write the complete state here (atomically) at the end, and every "
                          "--checkpoint-every frames");
  command->add_option("--checkpoint-every", *checkpoint_every, "Frames between checkpoints")
      ->check(CLI::PositiveNumber)
      ->needs(checkpoint_option);
  command
      ->add_option("--resume", *resume_path,
                   "Continue the run saved in this checkpoint (its scene is stored in it): "
                   "--frames more frames (default: the rest of the scene's), frames numbered on")
      ->check(CLI::ExistingFile);
  auto render_dir = std::make_shared<std::string>();
  auto render_every = std::make_shared<int>(1);
  auto size = std::make_shared<std::string>("800x600");
  auto mode = std::make_shared<std::string>("faces");
  auto video = std::make_shared<std::string>();
  auto highlight = std::make_shared<bool>(false);
  auto* render_option = command->add_option(
      "--render", *render_dir,
      "Render frames offscreen (OpenGL through EGL, no display needed) to DIR/frame_NNNNNN.png");
  command->add_option("--render-every", *render_every, "Frames between pictures (default 1)")
      ->check(CLI::PositiveNumber)
      ->needs(render_option);
  command->add_option("--size", *size, "Picture size WxH in pixels (default 800x600)")
      ->needs(render_option);
  command
      ->add_option("--mode", *mode,
                   "faces (textured), wire (edges over faces) or cut (cut faces only), as the "
                   "seed's demo keys F, G, C")
      ->needs(render_option);
  command
      ->add_option("--video", *video,
                   "Also write the pictures as an MP4 (H.264) through ffmpeg (30 frames/s)")
      ->needs(render_option);
  command
      ->add_flag("--highlight-active", *highlight,
                 "Outline the tetrahedra the blade is in (the seed's active tetrahedra)")
      ->needs(render_option);
  auto replay_path = std::make_shared<std::string>();
  command
      ->add_option("--replay", *replay_path,
                   "Replay a session recorded by incise view --record: its scene (as it was "
                   "run) fed the same tool poses; the same final mesh, bit for bit")
      ->check(CLI::ExistingFile);
  auto threads = std::make_shared<int>(0);
  add_threads_option(*command, *threads);
  return [=]() {
    const auto thread_limit = limit_threads(*threads);
    if (!resume_path->empty() && !scene_path->empty()) {
      throw InputError(*resume_path, 0,
                       "--resume takes the scene stored in the checkpoint: "
                       "give no scene file with it");
    }
    std::unique_ptr<Engine> engine;
    int replay_frames = -1;
    if (!replay_path->empty() && (!resume_path->empty() || !tool_path->empty())) {
      throw InputError(*replay_path, 0, "--replay takes neither --resume nor --tool");
    }
    if (!replay_path->empty()) {
      const SessionRecording recording = read_session(*replay_path);
      const SessionSegment& segment = recording.segments.back();
      if (!scene_path->empty() && load_scene(*scene_path).source_text != segment.scene_text) {
        std::cerr << "warning: " << *scene_path << " differs from the scene recorded in "
                  << *replay_path << "; the recorded one is replayed\n";
      }
      engine = replay_engine(segment);
      replay_frames = segment.frames();
    } else if (!resume_path->empty()) {
      engine = Engine::resume(*resume_path);
    } else {
      SceneDescription fresh = scene_path->empty() ? default_scene() : load_scene(*scene_path);
      if (!tool_path->empty() && fresh.tool.cutter == CutterKind::kNone) {
        fresh.tool.cutter = CutterKind::kSubdivision;  // a blade path given to cut with
      }
      engine = std::make_unique<Engine>(fresh);
    }
    const SceneDescription& scene = engine->scene();
    const std::string name = scene.file.empty() ? "default" : scene.file.stem().string();
    const int first_frame = engine->frame();
    const int frame_count = *frames >= 0         ? *frames
                            : replay_frames >= 0 ? replay_frames
                                                 : std::max(0, scene.frames - first_frame);
    const std::filesystem::path output =
        out->empty() ? scene.output_dir : std::filesystem::path(*out);
    if (!tool_path->empty()) {
      engine->set_tool_source(ScriptedToolPath::from_csv(*tool_path));
    }
    for (const std::string& warning : engine->warnings()) {
      std::cerr << "warning: " << warning << "\n";
    }
    std::cerr << fmt::format(
        "{}{}: {} vertices, {} tetrahedra, {:.4g} kg, {} with dt = {:.4g} s, {} frames\n",
        scene.file.empty() ? "default scene" : scene.file.string(),
        first_frame > 0 ? fmt::format(" resumed at frame {}", first_frame) : std::string(),
        engine->mesh().vertex_count(), engine->mesh().tet_count(), engine->total_mass(),
        engine->integrator().name(), scene.integrator.dt, frame_count);
    // Frames keep their global numbers: a resumed run continues the same series.
    VtuSeriesSink series(output, name, scene.vtu_every, first_frame + frame_count, first_frame > 0);
    engine->add_sink(series);
    std::optional<ToolPathRecorder> recorder;
    if (!record_path->empty()) {
      engine->add_sink(recorder.emplace(*record_path));
    }
    std::optional<CheckpointSink> checkpoints;
    if (!checkpoint->empty()) {
      engine->add_sink(checkpoints.emplace(*checkpoint, *checkpoint_every));
    }
    Pictures pictures;
    if (!render_dir->empty()) {
      PictureOptions options;
      options.dir = *render_dir;
      options.every = *render_every;
      options.last_frame = first_frame + frame_count;
      std::tie(options.render.width, options.render.height) = parse_size(*size);
      options.render.mode = parse_mode(*mode);
      options.highlight_active = *highlight;
      if (!video->empty()) {
        options.video = *video;
      }
#ifdef INCISE_HAVE_GL
      pictures.renderer = std::make_unique<OffscreenRenderer>();
#else
      throw InputError("--render: this incise was built without OpenGL (-DINCISE_WITH_GL=ON)");
#endif
      engine->add_sink(pictures.sink.emplace(*pictures.renderer, options));
    }
    Progress progress(first_frame, first_frame + frame_count);
    const auto start = Clock::now();
    auto elapsed = [&start] { return seconds_since(start); };
    const RunResult result = run(*engine, frame_count, [&](const FrameRecord& record) {
      progress.update(record, elapsed());
    });
    const double wall = elapsed();
    if (result.diverged) {
      progress.interrupt();
    }

    // Per-stage breakdown, named after the seed's Table 1.
    double sums[4] = {0, 0, 0, 0};
    for (const FrameRecord& record : result.frames) {
      sums[0] += record.cd;
      sums[1] += record.gc;
      sums[2] += record.rx;
      sums[3] += record.rd;
    }
    const double count = std::max<double>(1.0, static_cast<double>(result.frames.size()));
    const double total = sums[0] + sums[1] + sums[2] + sums[3];
    const char* names[4] = {"cd", "gc", "rx", "rd"};
    const char* meanings[4] = {"collision detection", "topology/geometry changes", "relaxation",
                               "rendering/output"};
    std::cout << fmt::format("\n{:<4} {:<28} {:>12} {:>8}\n", "", "stage", "ms/frame", "%");
    for (int k = 0; k < 4; ++k) {
      std::cout << fmt::format("{:<4} {:<28} {:>12.4f} {:>7.1f}%\n", names[k], meanings[k],
                               1e3 * sums[k] / count, total > 0.0 ? 100.0 * sums[k] / total : 0.0);
    }
    std::cout << fmt::format("{:<4} {:<28} {:>12.4f}   ({:.1f} frames/s, physics only {:.1f})\n",
                             "", "total", 1e3 * total / count, total > 0.0 ? count / total : 0.0,
                             sums[2] > 0.0 ? count / sums[2] : 0.0);
    // Turned inside out in the final state (the rest shape is checked when the mesh loads).
    const std::size_t inverted = inverted_at(engine->mesh(), engine->positions()).size();
    if (!result.frames.empty()) {
      const FrameRecord& last = result.frames.back();
      std::cout << fmt::format(
          "final: t = {:.4g} s, kinetic energy {:.4g} J, max displacement {:.4g} m, {} tets, {} "
          "inverted{}\n",
          last.time, last.kinetic_energy, last.max_displacement, last.tets, inverted,
          engine->guarded_tets() > 0
              ? fmt::format(" ({} pushed back right side out over the run, at most {} in a step)",
                            engine->guarded_tets(), engine->guarded_tets_most())
              : std::string());
    }
    std::cout << "ParaView series: " << series.pvd().string() << "\n";
    if (engine->visual() != nullptr) {
      std::cout << "visual surface series: " << series.visual_pvd().string() << "\n";
    }
    if (pictures.sink) {
      std::cout << fmt::format("pictures: {} in {}{}\n", pictures.sink->pictures().size(),
                               *render_dir, video->empty() ? "" : ", video: " + *video);
    }

    if (!report_path->empty()) {
      nlohmann::ordered_json report;
      report["scene"] = scene_path->empty() ? "default" : *scene_path;
      report["integrator"] = engine->integrator().name();
      report["dt"] = scene.integrator.dt;
      report["frame_dt"] = scene.frame_dt;
      report["frames_run"] = result.frames.size();
      report["vertices"] = engine->mesh().vertex_count();
      report["tets"] = engine->mesh().tet_count();
      report["kinetic_energy"] = result.frames.empty() ? 0.0 : result.frames.back().kinetic_energy;
      report["max_displacement"] =
          result.frames.empty() ? 0.0 : result.frames.back().max_displacement;
      report["inverted_tets"] = inverted;
      // What the inversion guard did to get there (summed over steps; most in one step).
      report["guarded_tets"] = engine->guarded_tets();
      report["guarded_tets_most_in_a_step"] = engine->guarded_tets_most();
      report["guard_vertices_moved_back"] = engine->backtracked_vertices();
      report["guard_vertices_moved_back_most_in_a_step"] = engine->backtracked_vertices_most();
      report["diverged"] = result.diverged;
      if (result.diverged) {
        report["divergence"] = result.divergence;
      }
      report["wall_seconds"] = wall;
      report["mean_ms"] = {{"cd", 1e3 * sums[0] / count},
                           {"gc", 1e3 * sums[1] / count},
                           {"rx", 1e3 * sums[2] / count},
                           {"rd", 1e3 * sums[3] / count},
                           {"total", 1e3 * total / count}};
      report["frames_per_second"] = total > 0.0 ? count / total : 0.0;
      report["pvd"] = series.pvd().string();
      if (engine->visual() != nullptr) {
        report["visual_pvd"] = series.visual_pvd().string();
        report["visual_surface"] = visual_surface_report(*engine->visual());
      }
      nlohmann::ordered_json per_frame = nlohmann::ordered_json::array();
      for (const FrameRecord& record : result.frames) {
        per_frame.push_back({{"frame", record.frame},
                             {"time", record.time},
                             {"cd", 1e3 * record.cd},
                             {"gc", 1e3 * record.gc},
                             {"rx", 1e3 * record.rx},
                             {"rd", 1e3 * record.rd},
                             {"solver_iterations", record.solver_iterations},
                             {"rx_parts", rx_parts_ms(record.rx_parts)},
                             {"vertices", record.vertices},
                             {"tets", record.tets},
                             {"kinetic_energy", record.kinetic_energy},
                             {"max_displacement", record.max_displacement},
                             {"cut", record.cut},
                             {"written", record.written}});
      }
      report["per_frame_ms"] = per_frame;
      write_file_atomically(*report_path, report.dump(2) + "\n");
    }
    if (result.diverged) {
      std::cerr << "error: " << result.divergence << "\n";
      return kExitDiverged;
    }
    return 0;
  };
}

}  // namespace incise::app
