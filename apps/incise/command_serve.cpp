// incise serve [SCENE] [--port 18944] [--bind 127.0.0.1] [--out DIR] [--exit-when-idle]
// [--port-file FILE]: the engine as an OpenIGTLink server. A device (incise device, a
// bridged haptic device, 3D Slicer) sends the scalpel's pose as TRANSFORM; the physics runs
// in real time on this thread, the 1 kHz haptic loop answers each pose with a force
// (SENSOR), and the deformed surface goes out as POLYDATA every frame. Devices may speak
// OpenIGTLink header version 1 or 2 (protocol 3, as 3D Slicer and PLUS do).
//
// SIGINT and SIGTERM are answered within a second whatever the physics is doing: a frame
// that has not ended 0.7 s after the signal is abandoned, and the final files are written
// from the last frame that did end.

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "commands.hpp"
#include "incise/batch/visual_report.hpp"
#include "incise/core/error.hpp"
#include "incise/engine/engine.hpp"
#include "incise/haptics/haptic_loop.hpp"
#include "incise/igtl/server.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/xfem/visual_surface.hpp"

namespace incise::app {
namespace {

std::atomic<bool> stop_requested{false};

void request_stop(int /*signal*/) {
  stop_requested = true;
}

struct ServeOptions {
  std::string scene;
  int port = 18944;
  std::string bind = "127.0.0.1";
  std::string out = "out/serve";
  bool exit_when_idle = false;
  std::string port_file;
  double max_seconds = 0.0;
};

nlohmann::json histogram_json(double p50, double p99, double max) {
  return {{"p50", p50}, {"p99", p99}, {"max", max}};
}

/// How long a frame may go on after SIGINT/SIGTERM before it is abandoned (s).
constexpr double kStopGrace = 0.7;

/// What the final report says beyond the mesh: how the session went.
struct SessionSummary {
  std::string scene;
  std::string ended;
  bool diverged = false;
  int frames = 0;
  double time = 0.0;             ///< s
  double physics_seconds = 0.0;  ///< s
  std::size_t tets_start = 0;
  double rest_volume_start = 0.0;
  int reaction_pushes = 0;
  double largest_reaction = 0.0;   ///< N
  std::uint64_t guarded_tets = 0;  ///< pushed back right side out, summed over steps
  nlohmann::ordered_json visual;   ///< the visual surface's report, if any
};

/// The last frame that ended, kept by the physics thread for the stop watchdog: what the
/// final files are written from when a frame never ends. Guarded by its mutex.
struct LastFrame {
  std::mutex mutex;
  SessionSummary summary;  ///< the session as of that frame
  std::uint64_t mesh_revision = 0;
  std::vector<Vec3> rest;  ///< m, refreshed when the mesh changes
  std::vector<Tet> tets;
  std::vector<Vec3> positions;  ///< m
};

/// final.vtu (unless diverged) and report.json in `out`, from `mesh` at `positions`.
void write_final_files(const std::filesystem::path& out, const SessionSummary& session,
                       const TetMesh& mesh, std::span<const Vec3> positions,
                       const HapticSpec& settings, const HapticStatistics& haptic,
                       const igtl::ServerCounters& counters) {
  // Nothing but finite positions goes to disk: a diverged run keeps its report only.
  std::filesystem::create_directories(out);
  const ValidationReport validation = validate(mesh);
  const SurfaceEdgeCheck boundary = check_boundary(mesh);
  if (!session.diverged) {
    // The deformed body, with its displacement from rest (ParaView: Warp By Vector, -1).
    std::vector<double> displacement;
    displacement.reserve(3 * positions.size());
    for (std::size_t i = 0; i < positions.size(); ++i) {
      const Vec3 d = positions[i] - mesh.rest_positions()[i];
      displacement.insert(displacement.end(), {d.x(), d.y(), d.z()});
    }
    VtuFields fields;
    fields.length_unit_m = 1.0;  // a scene's metres
    fields.point_data.push_back({"displacement", 3, std::move(displacement)});
    write_vtu(out / "final.vtu", mesh, positions, fields);
  }
  nlohmann::json dropped = nlohmann::json::object();
  for (std::size_t i = 0; i < igtl::kDropReasons; ++i) {
    dropped[std::string(igtl::name_of(static_cast<igtl::DropReason>(i)))] = counters.dropped[i];
  }
  nlohmann::json report = {
      {"scene", session.scene},
      {"ended", session.ended},
      {"frames", session.frames},
      {"simulated_time_s", session.time},
      {"physics_ms_per_frame",
       session.frames > 0 ? 1e3 * session.physics_seconds / session.frames : 0.0},
      {"tets_start", session.tets_start},
      {"tets", mesh.tet_count()},
      {"rest_volume_start_m3", session.rest_volume_start},
      {"rest_volume_m3", total_volume(mesh)},
      {"valid", validation.ok()},
      // Elements inside out in the deformed state (the rest mesh's validity is "valid").
      {"inverted_tets", session.diverged ? 0 : inverted_at(mesh, positions).size()},
      // What the inversion guard did to keep them so (model.inversion_guard).
      {"guarded_tets", session.guarded_tets},
      {"watertight", boundary.watertight()},
      {"clients", counters.clients},
      {"clients_refused", counters.refused},
      {"clients_disconnected_for_garbage", counters.disconnected_for_garbage},
      {"haptic",
       {{"rate_hz", settings.rate},
        {"realtime_priority", haptic.realtime},
        {"ticks", haptic.ticks},
        {"overruns", haptic.overruns},
        {"period_s", histogram_json(haptic.period_p50, haptic.period_p99, haptic.period_max)},
        {"pose_to_force_latency_s",
         histogram_json(haptic.latency_p50, haptic.latency_p99, haptic.latency_max)},
        {"largest_force_n", haptic.largest_force},
        {"largest_force_step_n", haptic.largest_step},
        {"reaction_pushes", session.reaction_pushes},
        {"largest_reaction_n", session.largest_reaction}}},
      {"messages",
       {{"received", counters.received},
        {"poses", counters.poses},
        {"sent", counters.sent},
        {"send_dropped", counters.send_dropped},
        {"dropped", dropped},
        {"dropped_total", counters.dropped_total()}}},
      {"units", "SI (m, s, N); OpenIGTLink messages carry millimetres"}};
  if (!session.visual.is_null()) {
    report["visual_surface"] = session.visual;
  }
  write_file_atomically(out / "report.json", report.dump(2) + "\n");
  std::cerr << fmt::format(
      "incise serve: {} after {} frames; {} -> {} tets; haptic period p50 {:.3f} / p99 {:.3f} / "
      "max {:.3f} ms; {} poses, {} dropped; wrote {}\n",
      session.ended, session.frames, session.tets_start, mesh.tet_count(), 1e3 * haptic.period_p50,
      1e3 * haptic.period_p99, 1e3 * haptic.period_max, counters.poses, counters.dropped_total(),
      out.string());
}

int serve(const ServeOptions& options) {
  const SceneDescription scene =
      options.scene.empty() ? default_scene() : load_scene(options.scene);
  if (scene.tool.cutter == CutterKind::kNone) {
    throw InputError(scene.file.string(), 0,
                     "incise serve needs a cutter: add \"cutter\": {\"type\": \"subdivision\"}");
  }
  Engine engine(scene);
  // The device moves in the world, where the body is now: the engine carries its poses back
  // to the rest frame the cutters cut in.
  auto live = std::make_unique<LiveToolPose>(PoseFrame::kWorld);
  LiveToolPose& live_pose = *live;
  engine.set_tool_source(std::move(live));
  const TetMesh& start_mesh = engine.mesh();
  const double rest_volume_start = total_volume(start_mesh);
  const std::size_t tets_start = start_mesh.tet_count();

  std::unique_ptr<igtl::Server> server;
  // The device's forces over a physics frame, summed on the haptic thread: their mean, reversed,
  // is the tissue's reaction (pushed on the collision surface when the scene embeds one).
  std::mutex reaction_mutex;
  Vec3 reaction_sum = Vec3::Zero();
  int reaction_samples = 0;
  HapticLoop haptics(scene.tool.haptics, [&](const Vec3& force, const DevicePose& pose) {
    server->send_force(force, pose.device_stamp);
    const std::lock_guard lock(reaction_mutex);
    reaction_sum += force;
    ++reaction_samples;
  });
  std::atomic<int> clients_seen{0};
  igtl::ServerOptions server_options;
  server_options.bind = options.bind;
  server_options.port = options.port;
  server_options.device = scene.tool.device;
  server_options.blade = scene.tool.blade;
  server = std::make_unique<igtl::Server>(
      server_options,
      [&](const DevicePose& pose) {
        haptics.post_pose(pose);
        live_pose.set(pose.blade);
      },
      [&](bool connected) {
        if (connected) {
          ++clients_seen;
          std::cerr << "incise serve: a device connected\n";
        } else {
          haptics.release();
          live_pose.lift();
          std::cerr << "incise serve: the device left\n";
        }
      });
  std::cout << fmt::format("incise serve: listening on {}:{} for TRANSFORM '{}'\n", options.bind,
                           server->port(), scene.tool.device)
            << std::flush;
  if (!options.port_file.empty()) {
    write_file_atomically(options.port_file, std::to_string(server->port()) + "\n");
  }

  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  haptics.start();
  server->start();

  LastFrame last;
  {
    last.summary.scene = scene.file.empty() ? "(default)" : scene.file.string();
    last.summary.tets_start = tets_start;
    last.summary.rest_volume_start = rest_volume_start;
    last.mesh_revision = start_mesh.revision();
    last.rest.assign(start_mesh.rest_positions().begin(), start_mesh.rest_positions().end());
    last.tets.assign(start_mesh.tets().begin(), start_mesh.tets().end());
    last.positions.assign(engine.positions().begin(), engine.positions().end());
  }
  // The stop watchdog: a frame still running kStopGrace after the signal (a solve that takes
  // long, geometry that never returns) is abandoned, the final files written from `last`.
  std::atomic<bool> loop_over{false};
  std::atomic<int> finisher{0};  // 1: this thread writes the final files; 2: the watchdog
  std::thread watchdog([&] {
    while (!stop_requested.load() && !loop_over.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const auto give_up =
        std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::nanoseconds>(
                                               std::chrono::duration<double>(kStopGrace));
    while (!loop_over.load() && std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    int nobody = 0;
    if (loop_over.load() || !finisher.compare_exchange_strong(nobody, 2)) {
      return;
    }
    server->stop();
    haptics.stop();
    const std::lock_guard lock(last.mutex);
    SessionSummary abandoned = last.summary;
    abandoned.ended = fmt::format(
        "stopped (SIGINT/SIGTERM); frame {} did not end within {} s and was abandoned: final "
        "files from frame {}",
        abandoned.frames + 1, kStopGrace, abandoned.frames);
    try {
      const TetMesh mesh(last.rest, last.tets);
      write_final_files(options.out, abandoned, mesh, last.positions, scene.tool.haptics,
                        haptics.statistics(), server->counters());
    } catch (const std::exception& error) {
      std::cerr << "incise serve: could not write the final files: " << error.what() << "\n";
      std::_Exit(kExitError);
    }
    std::_Exit(0);  // the abandoned frame's thread cannot be joined
  });

  // Physics in real time: frame k ends at k frame_dt of wall time (or as soon as it can).
  const auto start = std::chrono::steady_clock::now();
  const auto frame_period = std::chrono::duration<double>(scene.frame_dt);
  std::string ended = "stopped (SIGINT/SIGTERM)";
  bool diverged = false;
  int frames = 0;
  double physics_seconds = 0.0;
  std::shared_ptr<const ContactModel>
      reaction_model;  // the last model built on a collision surface
  std::uint64_t reaction_revision = 0;
  int reaction_pushes = 0;
  double largest_reaction = 0.0;  // N
  while (!stop_requested.load()) {
    // (Once the last device's poses are all cut: it may have left between two frames.)
    if (options.exit_when_idle && clients_seen.load() > 0 && !server->has_client() &&
        !live_pose.has_passed()) {
      ended = "idle (the last device left)";
      break;
    }
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (options.max_seconds > 0.0 && elapsed > options.max_seconds) {
      ended = "--max-seconds reached";
      break;
    }
    std::this_thread::sleep_until(
        start + std::chrono::duration_cast<std::chrono::nanoseconds>(frame_period * (frames + 1)));
    const auto frame_start = std::chrono::steady_clock::now();
    {
      Vec3 mean = Vec3::Zero();
      {
        const std::lock_guard lock(reaction_mutex);
        if (reaction_samples > 0) {
          mean = reaction_sum / reaction_samples;
        }
        reaction_sum = Vec3::Zero();
        reaction_samples = 0;
      }
      // The reaction goes to the nodes that carry the point the device touched.
      const VisualSurface* touched = engine.collision();
      if (touched != nullptr && reaction_model && reaction_model->has_surface &&
          mean.norm() > 0.0) {
        SurfacePoint at{reaction_model->triangle, reaction_model->barycentric};
        if (reaction_revision != touched->revision() ||
            at.triangle >= touched->triangles().size()) {
          // A split rebuilt the surface since: the anchor's nearest point on it now.
          at =
              nearest_surface_point(touched->triangles(), touched->on_cut(),
                                    touched->positions(engine.positions()), reaction_model->anchor);
        }
        if (at.triangle < touched->triangles().size()) {
          engine.push(at.triangle, at.barycentric, -mean);
          ++reaction_pushes;
          largest_reaction = std::max(largest_reaction, mean.norm());
        }
      }
    }
    if (!engine.step()) {
      ended = "diverged: " + engine.divergence();
      diverged = true;
      break;
    }
    ++frames;
    // Refresh the haptic loop's model around this frame's state.
    std::optional<BladePose> blade = engine.blade();
    if (!blade) {
      if (const auto pose = haptics.latest_pose()) {
        blade = pose->blade;
      }
    }
    // The device touches the collision surface and Slicer shows the visual one, when the
    // scene embeds them (XFEM); else both are the mesh's boundary.
    const auto boundary = engine.surface();
    const auto shown = engine.visual() != nullptr ? engine.visual_surface() : boundary;
    std::vector<Vec3> shown_positions;
    if (engine.visual() != nullptr) {
      shown_positions = engine.visual()->positions(engine.positions());
    }
    const std::span<const Vec3> shown_at =
        engine.visual() != nullptr ? std::span<const Vec3>(shown_positions) : engine.positions();
    if (blade) {
      const VisualSurface* touched = engine.collision();
      std::shared_ptr<const ContactModel> model;
      if (touched != nullptr && touched != engine.visual()) {
        const std::vector<Vec3> touched_at = touched->positions(engine.positions());
        model = std::make_shared<const ContactModel>(
            build_contact_model(touched->triangles(), touched->on_cut(), touched_at, *blade,
                                scene.material, scene.tool.haptics, engine.frame()));
      } else {
        model = std::make_shared<const ContactModel>(
            build_contact_model(shown->triangles, shown->on_cut, shown_at, *blade, scene.material,
                                scene.tool.haptics, engine.frame()));
      }
      haptics.set_model(model);
      reaction_model = touched != nullptr ? model : nullptr;
      reaction_revision = touched != nullptr ? touched->revision() : 0;
    }
    if (server->has_client()) {
      server->send_surface(igtl::encode_surface(shown->triangles, shown->on_cut, shown_at,
                                                server_options.surface_device,
                                                igtl::timestamp_of(engine.time())));
    }
    physics_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - frame_start).count();
    {
      const std::lock_guard lock(last.mutex);
      const TetMesh& now = engine.mesh();
      if (now.revision() != last.mesh_revision) {
        last.mesh_revision = now.revision();
        last.rest.assign(now.rest_positions().begin(), now.rest_positions().end());
        last.tets.assign(now.tets().begin(), now.tets().end());
        if (engine.visual() != nullptr) {
          last.summary.visual = visual_surface_report(*engine.visual());
        }
      }
      last.positions.assign(engine.positions().begin(), engine.positions().end());
      last.summary.frames = frames;
      last.summary.time = engine.time();
      last.summary.physics_seconds = physics_seconds;
      last.summary.reaction_pushes = reaction_pushes;
      last.summary.largest_reaction = largest_reaction;
      last.summary.guarded_tets = engine.guarded_tets();
    }
  }
  loop_over = true;
  int nobody = 0;
  if (!finisher.compare_exchange_strong(nobody, 1)) {
    // The watchdog gave up on this frame and is writing the final files; it ends the process.
    watchdog.join();
    return kExitError;
  }
  watchdog.join();
  server->stop();
  haptics.stop();
  SessionSummary session = last.summary;  // (the watchdog has gone: no lock needed)
  session.ended = ended;
  session.diverged = diverged;
  session.frames = frames;
  session.time = engine.time();
  session.physics_seconds = physics_seconds;
  session.reaction_pushes = reaction_pushes;
  session.largest_reaction = largest_reaction;
  session.guarded_tets = engine.guarded_tets();
  if (engine.visual() != nullptr) {
    session.visual = visual_surface_report(*engine.visual());
  }
  write_final_files(options.out, session, engine.mesh(), engine.positions(), scene.tool.haptics,
                    haptics.statistics(), server->counters());
  return diverged ? kExitDiverged : 0;
}

}  // namespace

Runner add_serve_command(CLI::App& app) {
  auto options = std::make_shared<ServeOptions>();
  CLI::App* command = app.add_subcommand(
      "serve",
      "Run a scene as an OpenIGTLink server: a device sends the scalpel's pose, gets "
      "forces at 1 kHz and the deformed surface every frame");
  command->add_option("scene", options->scene, "Scene file (default: the built-in scene)");
  command->add_option("--port", options->port, "TCP port (0: any free port)")
      ->check(CLI::Range(0, 65535));
  command->add_option("--bind", options->bind,
                      "Address to listen on (loopback unless asked; \"*\" for every interface)");
  command->add_option("--out", options->out, "Folder for final.vtu and report.json");
  command->add_flag("--exit-when-idle", options->exit_when_idle,
                    "Stop once a device has come and the last one has left");
  command->add_option("--port-file", options->port_file,
                      "Write the port listened on to this file (for --port 0)");
  command->add_option("--max-seconds", options->max_seconds, "Stop after this long (s)")
      ->check(CLI::NonNegativeNumber);
  return [options] { return serve(*options); };
}

}  // namespace incise::app
