#include "incise/igtl/tcp.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <thread>

#include "incise/core/error.hpp"

namespace incise::igtl {
namespace {

std::string system_error() {
  return std::strerror(errno);
}

in_addr resolve(const std::string& host) {
  in_addr address{};
  if (host == "*" || host == "0.0.0.0") {
    address.s_addr = htonl(INADDR_ANY);
    return address;
  }
  if (host == "localhost") {
    address.s_addr = htonl(INADDR_LOOPBACK);
    return address;
  }
  if (inet_pton(AF_INET, host.c_str(), &address) == 1) {
    return address;
  }
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), nullptr, &hints, &found) != 0 || found == nullptr) {
    throw InputError("unknown host '" + host + "'");
  }
  address = reinterpret_cast<sockaddr_in*>(found->ai_addr)->sin_addr;
  freeaddrinfo(found);
  return address;
}

void check_port(int port) {
  if (port < 0 || port > 65535) {
    throw InputError("port " + std::to_string(port) + " is not in [0, 65535]");
  }
}

}  // namespace

Socket& Socket::operator=(Socket&& other) noexcept {
  if (this != &other) {
    close();
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

void Socket::close() {
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

Socket listen_on(const std::string& address, int port) {
  check_port(port);
  Socket socket(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (!socket.valid()) {
    throw Error("cannot create a socket: " + system_error());
  }
  const int yes = 1;
  setsockopt(socket.fd(), SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  sockaddr_in where{};
  where.sin_family = AF_INET;
  where.sin_addr = resolve(address);
  where.sin_port = htons(static_cast<std::uint16_t>(port));
  if (bind(socket.fd(), reinterpret_cast<const sockaddr*>(&where), sizeof where) != 0) {
    throw Error("cannot listen on " + address + ":" + std::to_string(port) + ": " + system_error());
  }
  if (listen(socket.fd(), 4) != 0) {
    throw Error("cannot listen on " + address + ":" + std::to_string(port) + ": " + system_error());
  }
  return socket;
}

int local_port(const Socket& socket) {
  sockaddr_in where{};
  socklen_t size = sizeof where;
  if (getsockname(socket.fd(), reinterpret_cast<sockaddr*>(&where), &size) != 0) {
    return -1;
  }
  return ntohs(where.sin_port);
}

Socket connect_to(const std::string& host, int port, double timeout) {
  check_port(port);
  sockaddr_in where{};
  where.sin_family = AF_INET;
  where.sin_addr = resolve(host);
  where.sin_port = htons(static_cast<std::uint16_t>(port));
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  std::string last_error;
  do {
    Socket socket(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
    if (!socket.valid()) {
      throw Error("cannot create a socket: " + system_error());
    }
    if (connect(socket.fd(), reinterpret_cast<const sockaddr*>(&where), sizeof where) == 0) {
      return socket;
    }
    last_error = system_error();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  } while (std::chrono::steady_clock::now() < give_up);
  throw Error("cannot connect to " + host + ":" + std::to_string(port) + ": " + last_error);
}

void configure_stream(const Socket& socket) {
  const int flags = fcntl(socket.fd(), F_GETFL, 0);
  fcntl(socket.fd(), F_SETFL, flags | O_NONBLOCK);
  const int yes = 1;
  setsockopt(socket.fd(), IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
}

bool read_available(const Socket& socket, std::vector<std::uint8_t>& into) {
  std::uint8_t chunk[65536];
  while (true) {
    const ssize_t got = ::recv(socket.fd(), chunk, sizeof chunk, 0);
    if (got > 0) {
      into.insert(into.end(), chunk, chunk + got);
      continue;
    }
    if (got == 0) {
      return false;  // the peer closed
    }
    if (errno == EINTR) {
      continue;
    }
    return errno == EAGAIN || errno == EWOULDBLOCK;
  }
}

Outbox::Outbox(int fd, std::size_t backlog_limit, std::function<void()> on_backlog)
    : fd_(fd), limit_(backlog_limit), on_backlog_(std::move(on_backlog)) {}

bool Outbox::write_locked(std::span<const std::uint8_t> bytes) {
  while (!bytes.empty()) {
    const ssize_t put = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (put > 0) {
      bytes = bytes.subspan(static_cast<std::size_t>(put));
      continue;
    }
    if (put < 0 && errno == EINTR) {
      continue;
    }
    if (put < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      backlog_.insert(backlog_.end(), bytes.begin(), bytes.end());
      if (on_backlog_) {
        on_backlog_();
      }
      return true;
    }
    broken_ = true;
    return false;
  }
  return true;
}

bool Outbox::send(std::span<const std::uint8_t> message, bool droppable) {
  const std::lock_guard lock(mutex_);
  if (broken_ || (droppable && backlog_.size() > limit_) || backlog_.size() > 4 * limit_) {
    ++dropped_;
    return false;
  }
  ++sent_;
  if (!backlog_.empty()) {  // keep the order: behind what waits
    backlog_.insert(backlog_.end(), message.begin(), message.end());
    return true;
  }
  return write_locked(message);
}

bool Outbox::flush() {
  const std::lock_guard lock(mutex_);
  if (broken_ || backlog_.empty()) {
    return !broken_;
  }
  std::vector<std::uint8_t> waiting;
  waiting.swap(backlog_);
  return write_locked(waiting);
}

bool Outbox::waiting() const {
  const std::lock_guard lock(mutex_);
  return !backlog_.empty();
}

bool Outbox::broken() const {
  const std::lock_guard lock(mutex_);
  return broken_;
}

std::uint64_t Outbox::messages_sent() const {
  const std::lock_guard lock(mutex_);
  return sent_;
}

std::uint64_t Outbox::messages_dropped() const {
  const std::lock_guard lock(mutex_);
  return dropped_;
}

}  // namespace incise::igtl
