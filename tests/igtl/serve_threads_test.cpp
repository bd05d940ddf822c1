// Every thread `incise serve` runs, at once, on one body: a device process streaming blade
// poses over loopback and reading forces back, the server's network thread, the haptic loop,
// the physics stepping a corotational-FEM body (its element loops in parallel) on this thread,
// and a viewer reading the published snapshots. Run plainly it checks the cut and the
// messages; the ThreadSanitizer build (scripts/test.sh) runs it to find any data race
// between them.

#include <gtest/gtest.h>
#include <sys/socket.h>

#include <atomic>
#include <cerrno>
#include <thread>

#include "incise/engine/engine.hpp"
#include "incise/haptics/contact_model.hpp"
#include "incise/haptics/haptic_loop.hpp"
#include "incise/igtl/server.hpp"
#include "incise/igtl/wire.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/scene/scene.hpp"

namespace incise::igtl {
namespace {

// A 3 x 4 x 3-cell block held at its base; the blade enters from -y and crosses half of it.
constexpr const char* kScene = R"({
  "mesh": {"box": {"cells": [3, 4, 3], "size": [0.03, 0.04, 0.03], "tets_per_cell": 5}},
  "material": "liver",
  "model": {"type": "corotational-fem"},
  "integrator": {"type": "backward-euler", "dt": 0.01,
                 "solver": {"type": "cg", "preconditioner": "block-jacobi", "tolerance": 1e-6}},
  "fixed": [{"box": [[-1, -1, -1], [1, 1, 0.0001]]}],
  "gravity": [0, 0, -9.81],
  "tool": {"blade": {"length": 0.05, "axis": [0, 0, 1]}},
  "cutter": {"type": "subdivision"},
  "frames": 1000,
  "frame_dt": 0.01
})";

/// The blade at `k` of `poses`: vertical, x = 1.6 cm, tip 5 mm above the base, from 5 mm
/// before the block to half way across it.
BladePose blade_at(int k, int poses) {
  const double y = -0.005 + 0.025 * k / poses;
  return {0.0, Vec3(0.016, y, 0.005), Vec3(0.016, y, 0.055)};
}

TEST(ServeThreads, ADeviceCutsAnFemBodyWhileTheHapticLoopAndAViewerRun) {
  const SceneDescription scene = parse_scene(kScene, "serve_threads.json");
  Engine engine(scene);
  engine.publish_snapshots(true);
  auto live = std::make_unique<LiveToolPose>();
  LiveToolPose& live_pose = *live;
  engine.set_tool_source(std::move(live));
  const std::size_t tets_before = engine.mesh().tet_count();

  std::unique_ptr<Server> server;
  std::atomic<int> forces_handed_on{0};
  HapticLoop haptics(scene.tool.haptics, [&](const Vec3& force, const DevicePose& pose) {
    server->send_force(force, pose.device_stamp);
    ++forces_handed_on;
  });
  ServerOptions options;
  options.port = 0;
  options.device = scene.tool.device;
  options.blade = scene.tool.blade;
  server = std::make_unique<Server>(
      options,
      [&](const DevicePose& pose) {
        haptics.post_pose(pose);
        live_pose.set(pose.blade);
      },
      [&](bool connected) {
        if (!connected) {
          haptics.release();
          live_pose.lift();
        }
      });
  haptics.start();
  server->start();

  // The device: a pose a millisecond, reading whatever comes back, until told to stop.
  constexpr int kPoses = 60;
  std::atomic<bool> device_done{false};
  std::atomic<int> device_sent{0};
  std::size_t device_bytes = 0;
  std::thread device([&] {
    Socket socket = connect_to("127.0.0.1", server->port(), 5.0);
    configure_stream(socket);
    std::vector<std::uint8_t> incoming;
    for (int k = 0; k <= kPoses && !device_done.load(); ++k) {
      const auto message = encode_transform(frame_of_blade(blade_at(k, kPoses), options.blade),
                                            options.device, timestamp_of(1.0 + 0.01 * k));
      if (::send(socket.fd(), message.data(), message.size(), MSG_NOSIGNAL) < 0) {
        if (errno != EAGAIN && errno != EWOULDBLOCK) {
          break;
        }
        --k;  // the socket's buffer is full: the same pose again
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      ++device_sent;
      (void)read_available(socket, incoming);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    while (!device_done.load()) {
      (void)read_available(socket, incoming);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    device_bytes = incoming.size();
  });

  // The viewer: every new snapshot read whole.
  std::atomic<bool> viewer_done{false};
  std::atomic<int> snapshots_seen{0};
  std::atomic<int> bad_snapshots{0};
  std::thread viewer([&] {
    int last = -1;
    while (!viewer_done.load()) {
      const auto snapshot = engine.snapshots().latest();
      if (!snapshot || snapshot->frame == last) {
        std::this_thread::yield();
        continue;
      }
      bool ok = snapshot->frame > last && snapshot->surface != nullptr;
      for (const Triangle& triangle : snapshot->surface->triangles) {
        for (VertexId v : triangle) {
          ok = ok && static_cast<std::size_t>(v) < snapshot->positions.size() &&
               snapshot->positions[static_cast<std::size_t>(v)].allFinite();
        }
      }
      bad_snapshots += ok ? 0 : 1;
      last = snapshot->frame;
      ++snapshots_seen;
    }
  });

  // The physics, on this thread, as incise serve runs it: step, refresh the haptic model,
  // stream the surface. Until the device has sent its stroke and the blade has followed it.
  int frames = 0;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (std::chrono::steady_clock::now() < give_up) {
    ASSERT_TRUE(engine.step()) << engine.divergence();
    ++frames;
    if (const auto& blade = engine.blade()) {
      const auto surface = engine.surface();
      haptics.set_model(std::make_shared<const ContactModel>(
          build_contact_model(surface->triangles, surface->on_cut, engine.positions(), *blade,
                              scene.material, scene.tool.haptics, engine.frame())));
      if (server->has_client()) {
        server->send_surface(encode_surface(surface->triangles, surface->on_cut, engine.positions(),
                                            options.surface_device, timestamp_of(engine.time())));
      }
    }
    if (device_sent.load() > kPoses && frames > 5 && engine.blade() &&
        (engine.blade()->tip - blade_at(kPoses, kPoses).tip).norm() < 1e-9) {
      break;
    }
  }
  device_done = true;
  device.join();
  viewer_done = true;
  viewer.join();
  server->stop();
  haptics.stop();

  EXPECT_EQ(device_sent.load(), kPoses + 1);
  EXPECT_EQ(server->counters().poses, static_cast<std::uint64_t>(kPoses + 1));
  EXPECT_EQ(server->counters().dropped_total(), 0u);
  EXPECT_GT(forces_handed_on.load(), 0);
  EXPECT_GT(device_bytes, 0u) << "the device read nothing back";
  EXPECT_GT(engine.mesh().tet_count(), tets_before) << "the device's stroke cut nothing";
  EXPECT_TRUE(validate(engine.mesh()).ok());
  EXPECT_GT(snapshots_seen.load(), 0);
  EXPECT_EQ(bad_snapshots.load(), 0);
}

}  // namespace
}  // namespace incise::igtl
