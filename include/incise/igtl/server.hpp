#pragma once
// incise's OpenIGTLink server: one device client at a time on a TCP port (loopback unless
// asked), its TRANSFORMs checked and turned into blade poses, forces (SENSOR) and surfaces
// (POLYDATA) sent back. Whatever a client sends, the server keeps serving: bad messages are
// dropped and counted, a client that sends only garbage is disconnected, a second client is
// told it is busy (STATUS) and closed, a client that leaves never ends the session.
// Clients may speak OpenIGTLink header version 1 or 2 (protocol 3, as 3D Slicer and PLUS do);
// each is answered in the version of its last good message, and surfaces go to it once it has
// sent one.
//
// Thread rule: the server's own network thread reads, accepts and calls the callbacks;
// send_force() and send_surface() may be called from any thread (the haptic loop, the
// physics); counters() from any thread.

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "incise/haptics/haptic_loop.hpp"
#include "incise/igtl/tcp.hpp"
#include "incise/igtl/wire.hpp"

namespace incise::igtl {

/// Where and how `incise serve` listens (its command-line options).
struct ServerOptions {
  std::string bind = "127.0.0.1";             ///< loopback unless asked
  int port = 18944;                           ///< OpenIGTLink's registered port; 0: any free port
  std::string device = "Scalpel";             ///< the tool's TRANSFORM device name
  std::string force_device = "ScalpelForce";  ///< the SENSOR device name of forces sent
  std::string surface_device = "Tissue";      ///< the POLYDATA device name of surfaces sent
  BladeGeometry blade;                        ///< the blade in the tool's frame
  int garbage_limit = 8;           ///< consecutive bad messages before a client is dropped
  double stall_timeout = 2.0;      ///< s an incomplete message may wait before it is dropped
  std::size_t backlog = 8u << 20;  ///< bytes queued for a slow client before surfaces drop
};

/// What the server has seen and sent since it started (the serve report's `network`).
struct ServerCounters {
  std::uint64_t received = 0;                         ///< complete messages (and drops) read
  std::uint64_t poses = 0;                            ///< TRANSFORMs taken
  std::uint64_t sent = 0;                             ///< messages handed to clients
  std::uint64_t send_dropped = 0;                     ///< surfaces not sent to a slow client
  std::array<std::uint64_t, kDropReasons> dropped{};  ///< messages dropped, per reason
  std::uint64_t clients = 0;                          ///< clients served
  std::uint64_t refused = 0;                          ///< clients turned away (busy)
  std::uint64_t disconnected_for_garbage = 0;  ///< clients dropped after garbage_limit bad ones
  /// Messages dropped for any reason.
  [[nodiscard]] std::uint64_t dropped_total() const;
};

/// The OpenIGTLink server of `incise serve`: one client at a time (others are told busy), its
/// TRANSFORMs handed to `on_pose`, forces and surfaces sent back. Its network thread calls the
/// callbacks; send_force, send_surface, has_client and counters may be called from any thread.
class Server {
 public:
  /// Called on the network thread with each pose taken.
  using PoseCallback = std::function<void(const DevicePose&)>;
  /// Called on the network thread when a client connects (true) or goes (false).
  using ClientCallback = std::function<void(bool connected)>;

  /// Listens at once (throws Error when the address or port cannot be had).
  Server(ServerOptions options, PoseCallback on_pose, ClientCallback on_client);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// The port it listens on (the one chosen when 0 was asked).
  [[nodiscard]] int port() const { return port_; }
  /// Starts the network thread.
  void start();
  /// Stops the network thread and closes the connection, sending what waits first.
  void stop();
  /// The haptic force (N) for the pose stamped `stamp` (echoed so the device can time the
  /// round trip); dropped when no client is connected.
  void send_force(const Vec3& force, std::uint64_t stamp);
  /// A surface message (encode_surface, header version 1) for the connected client, if any,
  /// re-headed to the version it speaks.
  void send_surface(std::vector<std::uint8_t> message);
  /// Whether a client is connected.
  [[nodiscard]] bool has_client() const { return has_client_.load(); }
  /// A copy of the counters.
  [[nodiscard]] ServerCounters counters() const;

 private:
  struct Client;
  /// The connected client (a shared reference: it stays valid after a disconnect).
  [[nodiscard]] std::shared_ptr<Client> current_client() const;
  void run();
  void accept_client();
  void read_client();
  void handle(const MessageReader::Event& event);
  void drop(DropReason reason, bool counts_as_garbage);
  void close_client();
  void send_to_client(std::span<const std::uint8_t> message, bool droppable);

  ServerOptions options_;
  PoseCallback on_pose_;
  ClientCallback on_client_;
  Socket listener_;
  int port_ = 0;
  Socket wake_;  ///< eventfd: a sender left bytes waiting, or stop()
  std::atomic<bool> running_{false};
  std::atomic<bool> has_client_{false};
  std::thread thread_;
  mutable std::mutex client_mutex_;  ///< guards client_ (the pointer) for senders
  std::shared_ptr<Client> client_;
  mutable std::mutex counters_mutex_;
  ServerCounters counters_;
};

}  // namespace incise::igtl
