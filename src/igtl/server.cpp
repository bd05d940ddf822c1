#include "incise/igtl/server.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <numeric>

#include "incise/core/error.hpp"
#include "incise/igtl/extended_header.hpp"

namespace incise::igtl {

struct Server::Client {
  Client(Socket connected, std::size_t backlog, std::function<void()> on_backlog)
      : socket(std::move(connected)), outbox(socket.fd(), backlog, std::move(on_backlog)) {}
  Socket socket;
  Outbox outbox;
  MessageReader reader;
  int garbage_run = 0;           ///< bad messages in a row
  std::uint64_t last_stamp = 0;  ///< of the newest pose taken
  /// The header version of the client's last good message: replies go out in it (0 until it
  /// has sent one: then no surfaces go out, and other replies in version 1). Read by senders
  /// on any thread.
  std::atomic<std::uint16_t> version{0};
  std::atomic<std::uint32_t> next_message_id{1};
  std::optional<SteadyTime> partial_since;
};

std::uint64_t ServerCounters::dropped_total() const {
  return std::accumulate(dropped.begin(), dropped.end(), std::uint64_t{0});
}

Server::Server(ServerOptions options, PoseCallback on_pose, ClientCallback on_client)
    : options_(std::move(options)),
      on_pose_(std::move(on_pose)),
      on_client_(std::move(on_client)),
      listener_(listen_on(options_.bind, options_.port)),
      port_(local_port(listener_)),
      wake_(eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
  if (!wake_.valid()) {
    throw Error("cannot create the server's wake-up descriptor");
  }
}

std::shared_ptr<Server::Client> Server::current_client() const {
  const std::lock_guard lock(client_mutex_);
  return client_;
}

Server::~Server() {
  stop();
}

void Server::start() {
  if (running_.exchange(true)) {
    return;
  }
  thread_ = std::thread([this] { run(); });
}

void Server::stop() {
  running_ = false;
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t ignored = write(wake_.fd(), &one, sizeof one);
  if (thread_.joinable()) {
    thread_.join();
  }
  close_client();
}

void Server::send_to_client(std::span<const std::uint8_t> message, bool droppable) {
  const std::shared_ptr<Client> client = current_client();
  if (!client) {
    return;
  }
  const std::uint16_t version = client->version.load();
  bool sent = false;
  if (version != kHeaderVersion2) {
    sent = client->outbox.send(message, droppable);
  } else {
    const std::vector<std::uint8_t> reheaded =
        in_header_version({message.begin(), message.end()}, version, client->next_message_id++);
    sent = client->outbox.send(reheaded, droppable);
  }
  const std::lock_guard lock(counters_mutex_);
  ++(sent ? counters_.sent : counters_.send_dropped);
}

void Server::send_force(const Vec3& force, std::uint64_t stamp) {
  if (has_client()) {
    send_to_client(encode_force(force, options_.force_device, stamp), false);
  }
}

void Server::send_surface(std::vector<std::uint8_t> message) {
  // Not before the client has said which header version it reads.
  const std::shared_ptr<Client> client = current_client();
  if (client && client->version.load() != 0) {
    send_to_client(message, true);
  }
}

ServerCounters Server::counters() const {
  const std::lock_guard lock(counters_mutex_);
  return counters_;
}

void Server::run() {
  while (running_.load()) {
    const std::shared_ptr<Client> client = current_client();
    pollfd fds[3] = {{listener_.fd(), POLLIN, 0}, {wake_.fd(), POLLIN, 0}, {-1, 0, 0}};
    nfds_t count = 2;
    if (client) {
      fds[2] = {client->socket.fd(),
                static_cast<short>(POLLIN | (client->outbox.waiting() ? POLLOUT : 0)), 0};
      count = 3;
    }
    if (poll(fds, count, 20) < 0 && errno != EINTR) {
      break;
    }
    if ((fds[1].revents & POLLIN) != 0) {
      std::uint64_t value = 0;
      [[maybe_unused]] const ssize_t ignored = read(wake_.fd(), &value, sizeof value);
    }
    if ((fds[0].revents & POLLIN) != 0) {
      accept_client();
    }
    if (!client) {
      continue;
    }
    if (client->outbox.waiting() && !client->outbox.flush()) {
      close_client();
      continue;
    }
    if ((fds[2].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
      read_client();
    }
    if (current_client() != client) {
      continue;  // it left, or was sent away
    }
    // A message begun and never finished (a body shorter than its header says) is dropped.
    if (client->reader.partial()) {
      const SteadyTime now = std::chrono::steady_clock::now();
      if (!client->partial_since) {
        client->partial_since = now;
      } else if (std::chrono::duration<double>(now - *client->partial_since).count() >
                 options_.stall_timeout) {
        drop(DropReason::kTruncated, false);
        close_client();
      }
    } else {
      client->partial_since.reset();
    }
  }
}

void Server::accept_client() {
  Socket socket(accept4(listener_.fd(), nullptr, nullptr, SOCK_CLOEXEC));
  if (!socket.valid()) {
    return;
  }
  if (has_client()) {
    const auto busy =
        encode_status(kStatusBusy, "busy",
                      "incise serves one device at a time; another is connected", options_.device);
    [[maybe_unused]] const ssize_t ignored =
        ::send(socket.fd(), busy.data(), busy.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    const std::lock_guard lock(counters_mutex_);
    ++counters_.refused;
    return;  // closed as it goes out of scope
  }
  configure_stream(socket);
  const int wake_fd = wake_.fd();
  auto client = std::make_shared<Client>(std::move(socket), options_.backlog, [wake_fd] {
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t ignored = write(wake_fd, &one, sizeof one);
  });
  {
    const std::lock_guard lock(client_mutex_);
    client_ = client;
  }
  has_client_ = true;
  {
    const std::lock_guard lock(counters_mutex_);
    ++counters_.clients;
  }
  if (on_client_) {
    on_client_(true);
  }
}

void Server::read_client() {
  const std::shared_ptr<Client> client = current_client();
  if (!client) {
    return;
  }
  std::vector<std::uint8_t> bytes;
  const bool open = read_available(client->socket, bytes);
  client->reader.feed(bytes);
  while (const auto event = client->reader.next()) {
    handle(*event);
    if (current_client() != client) {
      return;  // disconnected for garbage
    }
  }
  if (client->reader.fatal()) {
    close_client();
    return;
  }
  if (!open) {
    if (client->reader.partial()) {
      drop(DropReason::kTruncated, false);
    }
    close_client();
  }
}

void Server::handle(const MessageReader::Event& event) {
  {
    const std::lock_guard lock(counters_mutex_);
    ++counters_.received;
  }
  if (const auto* dropped = std::get_if<MessageReader::Drop>(&event)) {
    drop(dropped->reason, true);
    if (dropped->reason == DropReason::kOversized) {
      close_client();
    }
    return;
  }
  const Message& message = std::get<Message>(event);
  if (const auto reason = check_message(message)) {
    drop(*reason, true);
    return;
  }
  const Header& header = message.header;
  if (const std::shared_ptr<Client> client = current_client()) {
    client->version = header.version;  // answered in the version it speaks
  }
  if (header.type == "GET_STATUS") {
    const auto ok = encode_status(kStatusOk, "", "incise serve", options_.device);
    send_to_client(ok, false);
    return;
  }
  if (header.type != "TRANSFORM") {
    drop(DropReason::kUnsupported, false);
    return;
  }
  if (message.device_name() != options_.device) {
    drop(DropReason::kOtherDevice, false);
    return;
  }
  const auto decoded = decode_transform(message);
  if (const auto* reason = std::get_if<DropReason>(&decoded)) {
    drop(*reason, true);
    return;
  }
  const std::shared_ptr<Client> client = current_client();
  if (!client) {
    return;
  }
  if (header.timestamp != 0 && header.timestamp < client->last_stamp) {
    drop(DropReason::kStale, false);
    return;
  }
  client->last_stamp = std::max(client->last_stamp, header.timestamp);
  client->garbage_run = 0;
  DevicePose pose;
  pose.blade = blade_in_frame(std::get<ToolFrame>(decoded), options_.blade);
  pose.device_time = header.seconds();
  pose.device_stamp = header.timestamp;
  pose.received = std::chrono::steady_clock::now();
  {
    const std::lock_guard lock(counters_mutex_);
    ++counters_.poses;
  }
  if (on_pose_) {
    on_pose_(pose);
  }
}

void Server::drop(DropReason reason, bool counts_as_garbage) {
  {
    const std::lock_guard lock(counters_mutex_);
    ++counters_.dropped[static_cast<std::size_t>(reason)];
  }
  if (!counts_as_garbage) {
    return;
  }
  const std::shared_ptr<Client> client = current_client();
  if (!client) {
    return;
  }
  const int code = reason == DropReason::kCrc ? kStatusChecksum : kStatusUnknownInstruction;
  send_to_client(encode_status(code, std::string(name_of(reason)),
                               "message dropped: " + std::string(name_of(reason)), options_.device),
                 true);
  if (++client->garbage_run >= options_.garbage_limit) {
    {
      const std::lock_guard lock(counters_mutex_);
      ++counters_.disconnected_for_garbage;
    }
    close_client();
  }
}

void Server::close_client() {
  std::shared_ptr<Client> client;
  {
    const std::lock_guard lock(client_mutex_);
    client.swap(client_);
  }
  if (!client) {
    return;
  }
  client->outbox.flush();
  shutdown(client->socket.fd(), SHUT_RDWR);
  has_client_ = false;
  if (on_client_) {
    on_client_(false);
  }
}

}  // namespace incise::igtl
