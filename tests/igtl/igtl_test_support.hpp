#pragma once
// What the OpenIGTLink tests share: a server running on a free loopback port that records the
// poses it takes, a wait for a condition, whole-stream sends and reads.

#include <gtest/gtest.h>
#include <sys/socket.h>

#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "incise/igtl/server.hpp"
#include "incise/igtl/wire.hpp"

namespace incise::igtl::test {

/// A started Server (any free port) whose pose callback keeps every pose.
struct RunningServer {
  std::mutex mutex;
  std::vector<DevicePose> poses;
  Server server;
  explicit RunningServer(ServerOptions options)
      : server(
            [&] {
              options.port = 0;
              return options;
            }(),
            [this](const DevicePose& pose) {
              const std::lock_guard lock(mutex);
              poses.push_back(pose);
            },
            {}) {
    server.start();
  }
  std::size_t pose_count() {
    const std::lock_guard lock(mutex);
    return poses.size();
  }
};

/// Waits (up to 3 s) for `condition`.
template <typename Condition>
bool eventually(Condition condition) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  while (std::chrono::steady_clock::now() < give_up) {
    if (condition()) {
      return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return condition();
}

inline void send_bytes(const Socket& socket, std::span<const std::uint8_t> bytes) {
  ASSERT_EQ(::send(socket.fd(), bytes.data(), bytes.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(bytes.size()));
}

/// Every complete message and drop in `bytes`.
inline std::vector<MessageReader::Event> read_all(std::span<const std::uint8_t> bytes) {
  MessageReader reader;
  reader.feed(bytes);
  std::vector<MessageReader::Event> events;
  while (auto event = reader.next()) {
    events.push_back(std::move(*event));
  }
  return events;
}

}  // namespace incise::igtl::test
