// OpenIGTLink as incise speaks it: every message type round trips, and a server that is fed
// malformed, oversized, stale or hostile messages drops and counts each, then still serves a
// good client.

#include <gtest/gtest.h>
#include <sys/socket.h>

#include <random>
#include <thread>

#include "igtl/igtl_test_support.hpp"
#include "incise/igtl/server.hpp"
#include "incise/igtl/wire.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"

namespace incise::igtl {
namespace {

using test::eventually;
using test::read_all;
using test::send_bytes;

Message only_message(std::span<const std::uint8_t> bytes) {
  auto events = read_all(bytes);
  EXPECT_EQ(events.size(), 1u);
  EXPECT_TRUE(std::holds_alternative<Message>(events.at(0)));
  Message message = std::get<Message>(events.at(0));
  EXPECT_FALSE(check_message(message).has_value());
  return message;
}

ToolFrame tilted_frame() {
  ToolFrame frame;
  frame.rotation = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  frame.translation = Vec3(0.012, -0.034, 0.056);
  return frame;
}

TEST(Wire, TransformRoundTrip) {
  const ToolFrame frame = tilted_frame();
  const std::uint64_t stamp = timestamp_of(1234.5);
  const Message message = only_message(encode_transform(frame, "Scalpel", stamp));
  EXPECT_EQ(message.header.type, "TRANSFORM");
  EXPECT_EQ(message.header.device, "Scalpel");
  EXPECT_EQ(message.header.version, 1);
  EXPECT_EQ(message.header.timestamp, stamp);
  EXPECT_NEAR(message.header.seconds(), 1234.5, 1e-6);
  const auto decoded = decode_transform(message);
  ASSERT_TRUE(std::holds_alternative<ToolFrame>(decoded));
  const ToolFrame& back = std::get<ToolFrame>(decoded);
  EXPECT_LT((back.rotation - frame.rotation).cwiseAbs().maxCoeff(), 1e-6);  // float32
  EXPECT_LT((back.translation - frame.translation).norm(), 1e-8);           // mm on the wire
}

TEST(Wire, BladeFrameRoundTrip) {
  BladeGeometry blade;
  blade.length = 0.048;
  blade.axis = Vec3(0, 0, 1);
  const BladePose pose{0.0, Vec3(0.02, 0.01, 0.012), Vec3(0.03, 0.0, 0.058)};
  const ToolFrame frame = frame_of_blade(pose, blade);
  const BladePose back = blade_in_frame(frame, blade);
  EXPECT_LT((back.tip - pose.tip).norm(), 1e-15);
  EXPECT_LT(((back.base - back.tip).normalized() - (pose.base - pose.tip).normalized()).norm(),
            1e-12);
  EXPECT_NEAR((back.base - back.tip).norm(), 0.048, 1e-15);  // the scene's length wins
}

TEST(Wire, ForceAndStatusRoundTrip) {
  const Message force = only_message(encode_force(Vec3(0.5, -1.25, 2.0), "ScalpelForce", 77));
  const auto values = decode_sensor(force);
  ASSERT_TRUE(std::holds_alternative<std::vector<double>>(values));
  EXPECT_EQ(std::get<std::vector<double>>(values), (std::vector<double>{0.5, -1.25, 2.0}));
  EXPECT_EQ(force.header.timestamp, 77u);

  const Message status = only_message(encode_status(kStatusBusy, "busy", "another device", "S"));
  const auto decoded = decode_status(status);
  ASSERT_TRUE(std::holds_alternative<Status>(decoded));
  EXPECT_EQ(std::get<Status>(decoded).code, kStatusBusy);
  EXPECT_EQ(std::get<Status>(decoded).error_name, "busy");
  EXPECT_EQ(std::get<Status>(decoded).text, "another device");
}

TEST(Wire, SurfaceRoundTripWithCutFacesMarked) {
  const TetMesh mesh = make_box_grid({{6, 6, 6}, Vec3(0.06, 0.06, 0.06), Vec3::Zero(), 6});
  std::vector<Triangle> triangles;
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    triangles.push_back(face.vertices);
  }
  std::vector<std::uint8_t> on_cut(triangles.size());
  for (std::size_t i = 0; i < on_cut.size(); ++i) {
    on_cut[i] = i % 3 == 0 ? 1 : 0;
  }
  const Message message =
      only_message(encode_surface(triangles, on_cut, mesh.rest_positions(), "Tissue", 5));
  const auto decoded = decode_surface(message);
  ASSERT_TRUE(std::holds_alternative<Surface>(decoded));
  const Surface& surface = std::get<Surface>(decoded);
  ASSERT_EQ(surface.triangles.size(), triangles.size());
  // The marks come as a point scalar, one value per point sent: the share of the point's
  // triangles that are cut faces.
  ASSERT_EQ(surface.cut_share.size(), surface.points.size());
  std::vector<std::array<int, 2>> uses(surface.points.size(), {0, 0});
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (VertexId corner : surface.triangles[i]) {
      ++uses[static_cast<std::size_t>(corner)][0];
      uses[static_cast<std::size_t>(corner)][1] += on_cut[i];
    }
  }
  for (std::size_t p = 0; p < uses.size(); ++p) {
    EXPECT_FLOAT_EQ(surface.cut_share[p], static_cast<float>(uses[p][1]) / uses[p][0]);
  }
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (std::size_t corner = 0; corner < 3; ++corner) {
      const Vec3 sent = mesh.rest_positions()[static_cast<std::size_t>(triangles[i][corner])];
      const Vec3 got = surface.points.at(static_cast<std::size_t>(surface.triangles[i][corner]));
      EXPECT_LT((sent - got).norm(), 1e-8);
    }
  }
  // Only the vertices the surface uses are sent.
  EXPECT_LT(surface.points.size(), mesh.vertex_count());
}

TEST(Wire, ReaderWaitsForWholeMessagesAndSkipsBadHeaders) {
  const auto good = encode_transform(tilted_frame(), "Scalpel", 1);
  MessageReader reader;
  reader.feed(std::span(good).first(30));
  EXPECT_FALSE(reader.next().has_value());
  EXPECT_TRUE(reader.partial());
  reader.feed(std::span(good).subspan(30));
  EXPECT_TRUE(reader.next().has_value());
  EXPECT_FALSE(reader.partial());

  // A version-3 header: dropped, its body skipped, the next message read.
  auto bad = good;
  bad[1] = 3;
  std::vector<std::uint8_t> stream = bad;
  stream.insert(stream.end(), good.begin(), good.end());
  const auto events = read_all(stream);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(std::get<MessageReader::Drop>(events[0]).reason, DropReason::kVersion);
  EXPECT_TRUE(std::holds_alternative<Message>(events[1]));
}

TEST(Wire, ArbitraryBytesNeverCrashTheReaderOrTheDecoders) {
  // Random garbage, good messages and their mutations, fed in random chunks: every event is a
  // drop or a message, decoders answer every message with a value or a reason, and a body
  // size beyond the limit stops the stream for good.
  std::mt19937_64 random(20261123);
  const auto transform = encode_transform(tilted_frame(), "Scalpel", 3);
  const auto force = encode_force(Vec3(1, 2, 3), "ScalpelForce", 4);
  const TetMesh mesh = make_box_grid({{2, 2, 2}, Vec3(0.02, 0.02, 0.02), Vec3::Zero(), 6});
  std::vector<Triangle> triangles;
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    triangles.push_back(face.vertices);
  }
  const auto surface = encode_surface(triangles, std::vector<std::uint8_t>(triangles.size(), 1),
                                      mesh.rest_positions(), "Tissue", 5);
  const std::vector<std::vector<std::uint8_t>> seeds = {transform, force, surface};
  int messages = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::vector<std::uint8_t> stream;
    for (int part = 0; part < 6; ++part) {
      std::vector<std::uint8_t> piece = seeds[random() % seeds.size()];
      const int flips = static_cast<int>(random() % 4);
      for (int f = 0; f < flips; ++f) {
        piece[random() % piece.size()] ^= static_cast<std::uint8_t>(1u << (random() % 8));
      }
      if (random() % 5 == 0) {
        piece.resize(random() % piece.size());
      }
      stream.insert(stream.end(), piece.begin(), piece.end());
    }
    MessageReader reader;
    std::size_t at = 0;
    while (at < stream.size()) {
      const std::size_t chunk = std::min<std::size_t>(1 + random() % 97, stream.size() - at);
      reader.feed(std::span(stream).subspan(at, chunk));
      at += chunk;
      while (const auto event = reader.next()) {
        if (const auto* message = std::get_if<Message>(&*event)) {
          ++messages;
          EXPECT_EQ(message->body.size(), message->header.body_size);
          (void)check_message(*message);
          (void)decode_transform(*message);
          (void)decode_sensor(*message);
          (void)decode_status(*message);
          (void)decode_surface(*message);
        }
      }
      if (reader.fatal()) {
        EXPECT_FALSE(reader.next().has_value());
        break;
      }
    }
  }
  EXPECT_GT(messages, 100);
}

// ---- the server under attack ----

void put_big_endian(std::vector<std::uint8_t>& bytes, std::size_t at, std::uint64_t value) {
  for (int i = 7; i >= 0; --i) {
    bytes[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(value & 0xff);
    value >>= 8;
  }
}

void refresh_crc(std::vector<std::uint8_t>& bytes) {
  put_big_endian(bytes, 50, body_crc(std::span(bytes).subspan(kHeaderSize)));
}

/// A server whose incomplete messages stall for 0.3 s at most.
struct StallingServer : test::RunningServer {
  StallingServer()
      : test::RunningServer([] {
          ServerOptions options;
          options.stall_timeout = 0.3;
          return options;
        }()) {}
};

/// Sends `bytes` from a fresh client, which then leaves; expects `reason` to be counted.
void expect_dropped(StallingServer& running, std::span<const std::uint8_t> bytes,
                    DropReason reason) {
  const std::uint64_t before = running.server.counters().dropped[static_cast<std::size_t>(reason)];
  {
    Socket client = connect_to("127.0.0.1", running.server.port(), 2.0);
    send_bytes(client, bytes);
    ASSERT_TRUE(eventually([&] {
      return running.server.counters().dropped[static_cast<std::size_t>(reason)] > before;
    })) << name_of(reason);
  }
  ASSERT_TRUE(eventually([&] { return !running.server.has_client(); }));
}

TEST(Server, DropsAndCountsEveryMalformedMessageThenServesAGoodClient) {
  StallingServer running;
  const ToolFrame frame = tilted_frame();
  const auto good = encode_transform(frame, "Scalpel", timestamp_of(10.0));

  expect_dropped(running, std::span(good).first(20), DropReason::kTruncated);  // short header
  auto version = good;
  version[1] = 9;
  expect_dropped(running, version, DropReason::kVersion);
  auto longer = good;  // a body larger than what is sent, then silence
  put_big_endian(longer, 42, 100);
  expect_dropped(running, longer, DropReason::kTruncated);
  auto huge = good;
  put_big_endian(huge, 42, std::uint64_t{1} << 63);
  expect_dropped(running, huge, DropReason::kOversized);
  auto crc = good;
  crc.back() ^= 0x5a;
  expect_dropped(running, crc, DropReason::kCrc);
  ToolFrame not_a_number = frame;
  not_a_number.rotation(1, 1) = std::nan("");
  expect_dropped(running, encode_transform(not_a_number, "Scalpel", 1), DropReason::kNotFinite);
  ToolFrame scaled = frame;
  scaled.rotation *= 2.0;
  expect_dropped(running, encode_transform(scaled, "Scalpel", 1), DropReason::kNotRigid);
  ToolFrame sheared = frame;
  sheared.rotation(0, 1) += 0.3;
  expect_dropped(running, encode_transform(sheared, "Scalpel", 1), DropReason::kNotRigid);
  auto unknown = good;
  std::copy_n("FOOBAR\0\0\0\0\0\0", 12, unknown.begin() + 2);
  expect_dropped(running, unknown, DropReason::kUnknownType);
  expect_dropped(running, encode_transform(frame, "", 1), DropReason::kBadName);
  auto short_body = good;  // a TRANSFORM of 40 bytes, honest size and CRC
  short_body.resize(kHeaderSize + 40);
  put_big_endian(short_body, 42, 40);
  refresh_crc(short_body);
  expect_dropped(running, short_body, DropReason::kBodySize);
  expect_dropped(running, encode_transform(frame, "Forceps", 1), DropReason::kOtherDevice);
  expect_dropped(running, encode_force(Vec3::Zero(), "Scalpel", 1), DropReason::kUnsupported);
  // Stale: a pose older than one already taken.
  {
    std::vector<std::uint8_t> both = good;
    const auto older = encode_transform(frame, "Scalpel", timestamp_of(9.0));
    both.insert(both.end(), older.begin(), older.end());
    expect_dropped(running, both, DropReason::kStale);
  }
  EXPECT_EQ(running.pose_count(), 1u);  // only the stale test's first pose got through

  // Garbage again and again: the client is sent away.
  {
    Socket client = connect_to("127.0.0.1", running.server.port(), 2.0);
    // The server may close the connection after its eighth bad message, so later sends
    // are allowed to fail (EPIPE / ECONNRESET) and end the loop.
    for (int i = 0; i < 12; ++i) {
      if (::send(client.fd(), crc.data(), crc.size(), MSG_NOSIGNAL) < 0) {
        break;
      }
    }
    ASSERT_TRUE(
        eventually([&] { return running.server.counters().disconnected_for_garbage == 1; }));
  }
  ASSERT_TRUE(eventually([&] { return !running.server.has_client(); }));

  // A good client still gets served: its pose arrives, forces and STATUS come back.
  Socket client = connect_to("127.0.0.1", running.server.port(), 2.0);
  send_bytes(client, encode_transform(frame, "Scalpel", timestamp_of(20.0)));
  ASSERT_TRUE(eventually([&] { return running.pose_count() == 2; }));
  {
    const std::lock_guard lock(running.mutex);
    EXPECT_LT((running.poses.back().blade.tip - frame.translation).norm(), 1e-8);
    EXPECT_EQ(running.poses.back().device_stamp, timestamp_of(20.0));
  }
  running.server.send_force(Vec3(0, 0, 1.5), timestamp_of(20.0));

  // A second device is told the server is busy, and does not disturb the first.
  {
    Socket second = connect_to("127.0.0.1", running.server.port(), 2.0);
    configure_stream(second);
    std::vector<std::uint8_t> bytes;
    ASSERT_TRUE(eventually([&] { return !read_available(second, bytes); }));  // closed
    const auto events = read_all(bytes);
    ASSERT_EQ(events.size(), 1u);
    const auto status = decode_status(std::get<Message>(events[0]));
    EXPECT_EQ(std::get<Status>(status).code, kStatusBusy);
    EXPECT_EQ(running.server.counters().refused, 1u);
  }
  configure_stream(client);
  std::vector<std::uint8_t> bytes;
  ASSERT_TRUE(eventually([&] {
    read_available(client, bytes);
    return bytes.size() >= kHeaderSize;
  }));
  const auto events = read_all(bytes);
  ASSERT_FALSE(events.empty());
  const auto force = decode_sensor(std::get<Message>(events[0]));
  EXPECT_EQ(std::get<std::vector<double>>(force), (std::vector<double>{0.0, 0.0, 1.5}));
  EXPECT_TRUE(running.server.has_client());
  EXPECT_EQ(running.server.counters().poses, 2u);
}

TEST(Server, ListensOnLoopbackUnlessAsked) {
  EXPECT_EQ(ServerOptions{}.bind, "127.0.0.1");
  ServerOptions elsewhere;
  elsewhere.bind = "203.0.113.7";  // not an address of this machine
  elsewhere.port = 0;
  EXPECT_THROW(Server(elsewhere, {}, {}), Error);
}

}  // namespace
}  // namespace incise::igtl
