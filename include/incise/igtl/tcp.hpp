#pragma once
// TCP for OpenIGTLink peers: POSIX sockets, written here because the library's own
// (igtl::ServerSocket, derived from an old vtkSocket) binds every interface with no way to
// keep a server on loopback, and blocks in Receive with no way to serve a 1 kHz loop and
// a misbehaving client at once. Messages themselves are the library's (wire.hpp).

#include <cstdint>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace incise::igtl {

/// An owned socket descriptor, closed when it goes.
class Socket {
 public:
  Socket() = default;
  /// Owns `fd`.
  explicit Socket(int fd) : fd_(fd) {}
  ~Socket() { close(); }
  /// Takes the other's descriptor.
  Socket(Socket&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  /// Closes its own descriptor, then takes the other's.
  Socket& operator=(Socket&& other) noexcept;
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;
  /// The descriptor (-1 when none).
  [[nodiscard]] int fd() const { return fd_; }
  /// Whether it holds a descriptor.
  [[nodiscard]] bool valid() const { return fd_ >= 0; }
  /// Closes the descriptor, if any.
  void close();

 private:
  int fd_ = -1;
};

/// A listening socket on `address` (an IPv4 address, "localhost" or "*" for every interface)
/// and `port` (0: any free port); throws Error naming the address on failure.
[[nodiscard]] Socket listen_on(const std::string& address, int port);
/// The port a socket is bound to.
[[nodiscard]] int local_port(const Socket& socket);
/// A connection to host:port, retried until `timeout` (s) passes (the server may be starting);
/// throws Error naming host and port.
[[nodiscard]] Socket connect_to(const std::string& host, int port, double timeout);
/// Non-blocking, no Nagle delay (a 1 kHz stream of small messages must not be batched).
void configure_stream(const Socket& socket);
/// Reads what is there (non-blocking): appended to `into`; false at end of stream or error.
bool read_available(const Socket& socket, std::vector<std::uint8_t>& into);

/// Whole messages out through a non-blocking socket, from any thread: what the kernel does
/// not take at once waits in a backlog that flush() sends when the socket is writable. A
/// droppable message (a surface) is refused when the backlog is over its limit, so a slow
/// reader gets fewer surfaces rather than stale forces.
class Outbox {
 public:
  /// Sends through `fd` (not owned); `on_backlog` is called when a message has to wait.
  Outbox(int fd, std::size_t backlog_limit, std::function<void()> on_backlog);
  /// Queues or sends `message` whole; false when it was dropped (backlog full or closed).
  bool send(std::span<const std::uint8_t> message, bool droppable);
  /// Sends what waits; false when the peer is gone.
  bool flush();
  /// Whether bytes wait in the backlog.
  [[nodiscard]] bool waiting() const;
  /// Whether a write failed (the peer is gone).
  [[nodiscard]] bool broken() const;
  /// Messages sent whole.
  [[nodiscard]] std::uint64_t messages_sent() const;
  /// Messages refused (backlog over its limit, or broken).
  [[nodiscard]] std::uint64_t messages_dropped() const;

 private:
  bool write_locked(std::span<const std::uint8_t> bytes);

  int fd_;
  std::size_t limit_;
  std::function<void()> on_backlog_;
  mutable std::mutex mutex_;
  std::vector<std::uint8_t> backlog_;
  bool broken_ = false;
  std::uint64_t sent_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace incise::igtl
