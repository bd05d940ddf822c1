// incise device PATH.csv [--host 127.0.0.1] [--port 18944] [--rate 1000] [--log FORCES.csv]:
// the reference device process. It plays a blade path (the CSV incise cut reads) in real time
// as OpenIGTLink TRANSFORMs, reads the forces the server answers with, logs them and prints
// its loop statistics. A real device's bridge is this loop with the path replaced by the
// device's pose and the logged force sent to its motors (README: "Bridge a device").

#include <fmt/format.h>

#include <chrono>
#include <fstream>
#include <iostream>
#include <thread>

#include "commands.hpp"
#include "incise/core/error.hpp"
#include "incise/haptics/haptic_loop.hpp"
#include "incise/igtl/extended_header.hpp"
#include "incise/igtl/tcp.hpp"
#include "incise/igtl/wire.hpp"
#include "incise/scene/scene.hpp"

namespace incise::app {
namespace {

struct DeviceOptions {
  std::string path;
  std::string host = "127.0.0.1";
  int port = 18944;
  std::string port_file;  ///< read the port from here (incise serve --port-file), if given
  double rate = 1000.0;
  std::string log;
  std::string name = "Scalpel";
  std::vector<double> axis = {0.0, 0.0, 1.0};
  double hold = 0.5;
  double connect_timeout = 10.0;
  int header_version = 1;
};

/// The port incise serve --port-file wrote (atomically) to `path`, waiting up to `timeout` s
/// for the file: the server may still be starting.
int port_from_file(const std::string& path, double timeout) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  for (;;) {
    std::ifstream in(path);
    int port = 0;
    if (in >> port && port >= 1 && port <= 65535) {
      return port;
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      throw InputError(path, 0, "holds no server port (incise serve --port-file writes one)");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

int run_device(DeviceOptions options) {
  const std::vector<BladePose> path = read_blade_path(options.path);
  if (path.empty()) {
    throw InputError(options.path, 0, "the blade path has no poses");
  }
  BladeGeometry blade;
  blade.axis = Vec3(options.axis[0], options.axis[1], options.axis[2]);
  if (!(blade.axis.norm() > 0.0) || !blade.axis.allFinite()) {
    throw InputError("--axis must be a non-zero vector");
  }
  blade.axis.normalize();
  std::ofstream log;
  if (!options.log.empty()) {
    log.open(options.log);
    if (!log) {
      throw InputError(options.log, 0, "cannot write the force log");
    }
    log << "t,fx,fy,fz\n";
  }

  if (!options.port_file.empty()) {
    options.port = port_from_file(options.port_file, options.connect_timeout);
  }
  igtl::Socket socket = igtl::connect_to(options.host, options.port, options.connect_timeout);
  igtl::configure_stream(socket);
  igtl::Outbox outbox(socket.fd(), 1u << 20, {});
  igtl::MessageReader reader;
  std::cerr << fmt::format(
      "incise device: connected to {}:{}, playing {} ({} poses, {:.3f} s) "
      "at {} Hz\n",
      options.host, options.port, options.path, path.size(), path.back().time - path.front().time,
      options.rate);

  DurationHistogram periods;
  DurationHistogram round_trips;
  std::uint64_t sent = 0;
  std::uint64_t forces = 0;
  std::uint64_t overruns = 0;
  std::uint64_t replies_in_other_version = 0;
  std::uint32_t message_id = 0;
  double largest_force = 0.0;
  // What 3D Slicer's OpenIGTLinkIF puts in a version-2 TRANSFORM's metadata.
  const std::vector<igtl::MetadataEntry> metadata = {{"MEMLNodeName", 3, "LinearTransform"}};
  const auto version = static_cast<std::uint16_t>(options.header_version);
  std::string refused;
  // The device's clock: seconds since boot (steady), so time stamps are never 0.
  const auto clock_seconds = [] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  const double start = clock_seconds();
  const double end = path.back().time - path.front().time + options.hold;
  const bool realtime = request_realtime_priority();
  PeriodicClock clock(options.rate);
  std::optional<SteadyTime> previous_tick;
  bool open = true;
  while (open) {
    const SteadyTime tick = clock.wait();
    overruns += clock.overran() ? 1 : 0;
    if (previous_tick) {
      periods.add(std::chrono::duration<double>(tick - *previous_tick).count());
    }
    previous_tick = tick;
    const double now = clock_seconds();
    const double t = now - start;
    if (t > end) {
      break;
    }
    const BladePose pose = pose_at(path, path.front().time + t);
    if (outbox.send(
            igtl::in_header_version(igtl::encode_transform(frame_of_blade(pose, blade),
                                                           options.name, igtl::timestamp_of(now)),
                                    version, ++message_id, metadata),
            false)) {
      ++sent;
    }
    outbox.flush();

    std::vector<std::uint8_t> bytes;
    open = igtl::read_available(socket, bytes);
    reader.feed(bytes);
    while (const auto event = reader.next()) {
      const auto* message = std::get_if<igtl::Message>(&*event);
      if (message == nullptr || igtl::check_message(*message)) {
        continue;  // the server's bytes are checked like anyone's
      }
      // The server answers a device in the header version it speaks.
      replies_in_other_version += message->header.version != version ? 1 : 0;
      if (message->header.type == "SENSOR") {
        const auto values = igtl::decode_sensor(*message);
        const auto* force = std::get_if<std::vector<double>>(&values);
        if (force == nullptr || force->size() != 3) {
          continue;
        }
        ++forces;
        largest_force = std::max(largest_force, Vec3((*force)[0], (*force)[1], (*force)[2]).norm());
        if (message->header.timestamp != 0) {
          round_trips.add(clock_seconds() - message->header.seconds());
        }
        if (log) {
          log << fmt::format("{:.6f},{:.9g},{:.9g},{:.9g}\n", clock_seconds() - start, (*force)[0],
                             (*force)[1], (*force)[2]);
        }
      } else if (message->header.type == "STATUS") {
        const auto status = igtl::decode_status(*message);
        if (const auto* decoded = std::get_if<igtl::Status>(&status);
            decoded != nullptr && decoded->code != igtl::kStatusOk) {
          std::cerr << fmt::format("incise device: server status {} ({}): {}\n", decoded->code,
                                   decoded->error_name, decoded->text);
          if (decoded->code == igtl::kStatusBusy) {
            refused = decoded->text;
          }
        }
      }
    }
    if (reader.fatal()) {
      break;
    }
  }
  socket.close();
  std::cout << fmt::format(
      "incise device: {} poses sent, {} forces received (largest {:.3f} N); loop period p50 "
      "{:.3f} / p99 {:.3f} / max {:.3f} ms, {} overruns; pose-to-force round trip p50 {:.3f} / "
      "p99 {:.3f} / max {:.3f} ms{}; header version {}, {} replies in another\n",
      sent, forces, largest_force, 1e3 * periods.quantile(0.5), 1e3 * periods.quantile(0.99),
      1e3 * periods.max(), overruns, 1e3 * round_trips.quantile(0.5),
      1e3 * round_trips.quantile(0.99), 1e3 * round_trips.max(),
      realtime ? " (real-time priority)" : "", version, replies_in_other_version);
  if (!refused.empty()) {
    std::cerr << "incise device: the server refused this device: " << refused << "\n";
    return kExitError;
  }
  return 0;
}

}  // namespace

Runner add_device_command(CLI::App& app) {
  auto options = std::make_shared<DeviceOptions>();
  CLI::App* command =
      app.add_subcommand("device",
                         "The reference device process: play a blade path to incise serve over "
                         "OpenIGTLink, log the forces it answers with");
  command->add_option("path", options->path, "Blade path CSV (t,tip_x,...,base_z; s, m)")
      ->required();
  command->add_option("--host", options->host, "Server address");
  auto* port =
      command->add_option("--port", options->port, "Server port")->check(CLI::Range(1, 65535));
  command
      ->add_option("--port-file", options->port_file,
                   "Read the server's port from this file (incise serve --port-file), waiting "
                   "for it up to --connect-timeout")
      ->excludes(port);
  command->add_option("--rate", options->rate, "Poses per second (Hz)")
      ->check(CLI::Range(1.0, 20000.0));
  command->add_option("--log", options->log, "Write the forces here (CSV: t,fx,fy,fz; s, N)");
  command->add_option("--name", options->name, "Device name of the TRANSFORMs");
  command->add_option("--axis", options->axis, "The blade's axis in the tool frame (3 numbers)")
      ->expected(3);
  command->add_option("--hold", options->hold, "Keep sending the last pose this long (s)")
      ->check(CLI::NonNegativeNumber);
  command
      ->add_option("--header-version", options->header_version,
                   "OpenIGTLink header version to send: 1, or 2 (protocol 3, with an extended "
                   "header and metadata, as 3D Slicer and PLUS send)")
      ->check(CLI::Range(1, 2));
  command
      ->add_option("--connect-timeout", options->connect_timeout,
                   "Keep trying to connect this long (s)")
      ->check(CLI::NonNegativeNumber);
  return [options] { return run_device(*options); };
}

}  // namespace incise::app
