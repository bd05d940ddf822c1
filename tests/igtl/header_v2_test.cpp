// OpenIGTLink header version 2 (protocol 3), as 3D Slicer's OpenIGTLinkIF and PLUS send it.
// The messages here are put together byte by byte from the protocol's description, with a
// CRC-64 written here too, so the tests check incise against the specification rather than
// against its own encoder.

#include <gtest/gtest.h>
#include <sys/socket.h>

#include <bit>
#include <cstring>
#include <thread>

#include "igtl/igtl_test_support.hpp"
#include "incise/igtl/extended_header.hpp"
#include "incise/igtl/server.hpp"
#include "incise/igtl/wire.hpp"

namespace incise::igtl {
namespace {

using test::eventually;
using test::read_all;
using test::send_bytes;

/// CRC-64 of ECMA-182 as OpenIGTLink uses it: polynomial 0x42F0E1EBA9EA3693, most significant
/// bit first, starting from 0, nothing XORed at the end.
std::uint64_t spec_crc64(std::span<const std::uint8_t> bytes) {
  std::uint64_t crc = 0;
  for (std::uint8_t byte : bytes) {
    crc ^= static_cast<std::uint64_t>(byte) << 56;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & (std::uint64_t{1} << 63)) != 0 ? (crc << 1) ^ 0x42F0E1EBA9EA3693ULL : crc << 1;
    }
  }
  return crc;
}

void put(std::vector<std::uint8_t>& bytes, std::uint64_t value, int size) {
  for (int i = size - 1; i >= 0; --i) {
    bytes.push_back(static_cast<std::uint8_t>((value >> (8 * i)) & 0xff));
  }
}

void put_text(std::vector<std::uint8_t>& bytes, std::string_view text, std::size_t width) {
  for (std::size_t i = 0; i < width; ++i) {
    bytes.push_back(i < text.size() ? static_cast<std::uint8_t>(text[i]) : 0);
  }
}

std::uint64_t get(std::span<const std::uint8_t> bytes, std::size_t at, int size) {
  std::uint64_t value = 0;
  for (int i = 0; i < size; ++i) {
    value = (value << 8) | bytes[at + static_cast<std::size_t>(i)];
  }
  return value;
}

/// A TRANSFORM's content (transform.md): R11 R21 R31 R12 R22 R32 R13 R23 R33 TX TY TZ as
/// big-endian float32, the translation in mm.
std::vector<std::uint8_t> transform_content(const Mat3& rotation, const Vec3& translation_mm) {
  std::vector<std::uint8_t> content;
  for (int column = 0; column < 3; ++column) {
    for (int row = 0; row < 3; ++row) {
      put(content, std::bit_cast<std::uint32_t>(static_cast<float>(rotation(row, column))), 4);
    }
  }
  for (int row = 0; row < 3; ++row) {
    put(content, std::bit_cast<std::uint32_t>(static_cast<float>(translation_mm[row])), 4);
  }
  return content;
}

struct Parts {
  std::uint16_t extended_size = 12;
  std::optional<std::uint16_t> metadata_header_size;  ///< default: 2 + 8 n
  std::optional<std::uint32_t> metadata_size;         ///< default: the keys' and values' bytes
  std::optional<std::uint16_t> count;                 ///< default: n
  std::uint32_t message_id = 42;
};

/// A header-version-2 message put together from the specification (header.md and the
/// version 3 description): header, extended header, content, metadata header, metadata.
std::vector<std::uint8_t> spec_v2_message(std::string_view type, std::string_view device,
                                          std::uint64_t timestamp,
                                          std::span<const std::uint8_t> content,
                                          const std::vector<MetadataEntry>& metadata,
                                          const Parts& parts = {}) {
  std::uint32_t value_bytes = 0;
  for (const MetadataEntry& entry : metadata) {
    value_bytes += static_cast<std::uint32_t>(entry.key.size() + entry.value.size());
  }
  std::vector<std::uint8_t> body;
  put(body, parts.extended_size, 2);
  put(body,
      parts.metadata_header_size.value_or(static_cast<std::uint16_t>(2 + 8 * metadata.size())), 2);
  put(body, parts.metadata_size.value_or(value_bytes), 4);
  put(body, parts.message_id, 4);
  for (int extra = 12; extra < parts.extended_size; ++extra) {
    body.push_back(0xee);  // fields of a later extended header, to be skipped
  }
  body.insert(body.end(), content.begin(), content.end());
  put(body, parts.count.value_or(static_cast<std::uint16_t>(metadata.size())), 2);
  for (const MetadataEntry& entry : metadata) {
    put(body, entry.key.size(), 2);
    put(body, entry.encoding, 2);
    put(body, entry.value.size(), 4);
  }
  for (const MetadataEntry& entry : metadata) {
    body.insert(body.end(), entry.key.begin(), entry.key.end());
    body.insert(body.end(), entry.value.begin(), entry.value.end());
  }
  std::vector<std::uint8_t> message;
  put(message, 2, 2);
  put_text(message, type, 12);
  put_text(message, device, 20);
  put(message, timestamp, 8);
  put(message, body.size(), 8);
  put(message, spec_crc64(body), 8);
  message.insert(message.end(), body.begin(), body.end());
  return message;
}

/// Why `bytes` (one message) is refused, by the reader or by check_message; nothing if not.
std::optional<DropReason> refusal(std::span<const std::uint8_t> bytes) {
  const auto events = read_all(bytes);
  EXPECT_EQ(events.size(), 1u);
  if (const auto* drop = std::get_if<MessageReader::Drop>(&events.at(0))) {
    return drop->reason;
  }
  return check_message(std::get<Message>(events.at(0)));
}

const Mat3 kRotation = Eigen::AngleAxisd(0.4, Vec3(0.2, -1, 0.5).normalized()).toRotationMatrix();
const Vec3 kTranslationMm(12.5, -34.0, 56.25);
const std::vector<MetadataEntry> kSlicerMetadata = {{"MEMLNodeName", 3, "LinearTransform"}};

TEST(HeaderVersion2, ASpecTransformIsReadWithItsMetadataAndMessageId) {
  const auto content = transform_content(kRotation, kTranslationMm);
  const auto bytes =
      spec_v2_message("TRANSFORM", "Scalpel", timestamp_of(3.5), content, kSlicerMetadata);
  const auto events = read_all(bytes);
  ASSERT_EQ(events.size(), 1u);
  const Message& message = std::get<Message>(events[0]);
  EXPECT_FALSE(check_message(message).has_value());
  EXPECT_EQ(message.header.version, 2);
  EXPECT_EQ(message.content_size, 48u);
  EXPECT_EQ(message.message_id, 42u);
  EXPECT_EQ(message.metadata, kSlicerMetadata);
  EXPECT_EQ(message.device_name(), "Scalpel");
  const auto frame = decode_transform(message);
  ASSERT_TRUE(std::holds_alternative<ToolFrame>(frame));
  EXPECT_LT((std::get<ToolFrame>(frame).rotation - kRotation).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((std::get<ToolFrame>(frame).translation - kTranslationMm / 1000.0).norm(), 1e-8);

  // A later extended header's extra fields are skipped; no metadata at all is fine too.
  Parts longer;
  longer.extended_size = 20;
  EXPECT_FALSE(refusal(spec_v2_message("TRANSFORM", "Scalpel", 1, content, {}, longer)));
  Parts bare;
  bare.metadata_header_size = 0;
  auto no_metadata_header = spec_v2_message("TRANSFORM", "Scalpel", 1, content, {}, bare);
  no_metadata_header.resize(no_metadata_header.size() - 2);  // no index count either
  // (the body size and CRC in the header no longer fit: write them again)
  std::vector<std::uint8_t> fixed(no_metadata_header.begin(), no_metadata_header.begin() + 42);
  const std::span<const std::uint8_t> body = std::span(no_metadata_header).subspan(kHeaderSize);
  put(fixed, body.size(), 8);
  put(fixed, spec_crc64(body), 8);
  fixed.insert(fixed.end(), body.begin(), body.end());
  const auto events_bare = read_all(fixed);
  ASSERT_EQ(events_bare.size(), 1u);
  ASSERT_TRUE(std::holds_alternative<Message>(events_bare[0]));
  EXPECT_EQ(std::get<Message>(events_bare[0]).content_size, 48u);
  EXPECT_FALSE(check_message(std::get<Message>(events_bare[0])));
}

TEST(HeaderVersion2, IncisesOwnVersion2MessagesAreTheSpecificationsBytes) {
  // The library packs version 1; in_header_version wraps it as the specification says.
  ToolFrame frame;
  frame.rotation = kRotation;
  frame.translation = kTranslationMm / 1000.0;
  const auto v1 = encode_transform(frame, "Scalpel", timestamp_of(3.5));
  EXPECT_EQ(in_header_version(v1, 1, 42, kSlicerMetadata), v1);
  const auto v2 = in_header_version(v1, 2, 42, kSlicerMetadata);
  const auto content = std::span(v1).subspan(kHeaderSize);
  const auto expected =
      spec_v2_message("TRANSFORM", "Scalpel", timestamp_of(3.5),
                      std::vector<std::uint8_t>(content.begin(), content.end()), kSlicerMetadata);
  EXPECT_EQ(v2, expected);
  // And the library's CRC is the specification's.
  EXPECT_EQ(body_crc(std::span(v2).subspan(kHeaderSize)),
            spec_crc64(std::span(v2).subspan(kHeaderSize)));
}

TEST(HeaderVersion2, BodiesWhosePartsDoNotAddUpAreRefusedWhateverTheySay) {
  const auto content = transform_content(kRotation, kTranslationMm);
  const auto message = [&](const Parts& parts, std::vector<MetadataEntry> metadata = {}) {
    return spec_v2_message("TRANSFORM", "Scalpel", 1, content, metadata, parts);
  };
  Parts short_extended;
  short_extended.extended_size = 8;
  EXPECT_EQ(refusal(message(short_extended)), DropReason::kExtendedHeader);
  Parts huge_metadata;
  huge_metadata.metadata_size = 0xffffffffu;
  EXPECT_EQ(refusal(message(huge_metadata, kSlicerMetadata)), DropReason::kExtendedHeader);
  // An extended header that says it is 65,535 bytes long in a body of 80.
  auto overrun = message({});
  overrun[kHeaderSize] = 0xff;
  overrun[kHeaderSize + 1] = 0xff;
  const auto overrun_body = std::span(overrun).subspan(kHeaderSize);
  const std::uint64_t overrun_crc = spec_crc64(overrun_body);
  for (int i = 0; i < 8; ++i) {
    overrun[50 + static_cast<std::size_t>(i)] =
        static_cast<std::uint8_t>((overrun_crc >> (56 - 8 * i)) & 0xff);
  }
  EXPECT_EQ(refusal(overrun), DropReason::kExtendedHeader);
  // A larger extended header whose extra fields are there is fine (checked above).
  Parts wrong_count;
  wrong_count.count = 3;
  EXPECT_EQ(refusal(message(wrong_count, kSlicerMetadata)), DropReason::kMetadata);
  Parts wrong_header_size;
  wrong_header_size.metadata_header_size = 2 + 8 * 2;
  wrong_header_size.count = 2;
  EXPECT_EQ(refusal(message(wrong_header_size, kSlicerMetadata)), DropReason::kMetadata);
  Parts wrong_values;
  wrong_values.metadata_size = 3;  // fits in the body, but is not what the entries hold
  EXPECT_EQ(refusal(message(wrong_values, kSlicerMetadata)), DropReason::kMetadata);
  std::vector<MetadataEntry> many(kMaxMetadataEntries + 1, MetadataEntry{"k", 3, "v"});
  EXPECT_EQ(refusal(message({}, many)), DropReason::kMetadata);
  EXPECT_FALSE(refusal(
      message({}, std::vector<MetadataEntry>(kMaxMetadataEntries, MetadataEntry{"k", 3, "v"}))));
  // A body damaged on the way: the CRC says so, whichever part it hit.
  auto damaged = message({}, kSlicerMetadata);
  damaged[kHeaderSize + 1] ^= 0x40;  // the metadata header's size
  EXPECT_EQ(refusal(damaged), DropReason::kCrc);
  auto damaged_content = message({}, kSlicerMetadata);
  damaged_content[kHeaderSize + 12 + 5] ^= 0x01;
  EXPECT_EQ(refusal(damaged_content), DropReason::kCrc);
  // A device name carried in metadata must be a name.
  EXPECT_EQ(refusal(message({}, {{"DeviceName", 3, std::string("bad\nname")}})),
            DropReason::kBadName);
}

// ---- the server speaks each client's version ----

/// A server taking TRANSFORMs from `device`.
struct DeviceServer : test::RunningServer {
  explicit DeviceServer(std::string device)
      : test::RunningServer([&] {
          ServerOptions options;
          options.device = std::move(device);
          return options;
        }()) {}
};

/// Reads whole messages from `socket` until `count` have come (up to 3 s), checking each
/// against the specification: its version's layout and the CRC over its whole body.
std::vector<std::vector<std::uint8_t>> receive(const Socket& socket, std::size_t count) {
  std::vector<std::uint8_t> bytes;
  std::vector<std::vector<std::uint8_t>> messages;
  eventually([&] {
    read_available(socket, bytes);
    while (bytes.size() >= kHeaderSize) {
      const std::uint64_t body_size = get(bytes, 42, 8);
      if (bytes.size() < kHeaderSize + body_size) {
        break;
      }
      messages.emplace_back(bytes.begin(),
                            bytes.begin() + static_cast<std::ptrdiff_t>(kHeaderSize + body_size));
      bytes.erase(bytes.begin(),
                  bytes.begin() + static_cast<std::ptrdiff_t>(kHeaderSize + body_size));
    }
    return messages.size() >= count;
  });
  for (const auto& message : messages) {
    const auto body = std::span(message).subspan(kHeaderSize);
    EXPECT_EQ(get(message, 50, 8), spec_crc64(body));
    if (get(message, 0, 2) == 2) {
      // extended header + content + metadata header (+ metadata) fill the body exactly
      EXPECT_GE(get(body, 0, 2), 12u);
      const std::uint64_t parts = get(body, 0, 2) + get(body, 2, 2) + get(body, 4, 4);
      EXPECT_LE(parts, body.size());
    }
  }
  return messages;
}

TEST(HeaderVersion2, TheServerTakesVersion2PosesAndAnswersInTheVersionEachClientSpeaks) {
  // A name longer than the header's 20 characters, carried in metadata.
  const std::string long_name = "PLUS_Stylus_To_Reference_Scalpel";
  DeviceServer running(long_name);
  const auto content = transform_content(kRotation, kTranslationMm);
  {
    Socket client = connect_to("127.0.0.1", running.server.port(), 2.0);
    configure_stream(client);
    // The header's name alone is cut at 20 characters: another device.
    send_bytes(client, spec_v2_message("TRANSFORM", long_name.substr(0, 20), timestamp_of(1.0),
                                       content, kSlicerMetadata));
    std::vector<MetadataEntry> named = kSlicerMetadata;
    named.push_back({"DeviceName", 3, long_name});
    send_bytes(client, spec_v2_message("TRANSFORM", long_name.substr(0, 20), timestamp_of(2.0),
                                       content, named));
    ASSERT_TRUE(eventually([&] { return running.pose_count() == 1; }));
    EXPECT_EQ(running.server.counters().dropped[static_cast<std::size_t>(DropReason::kOtherDevice)],
              1u);
    {
      const std::lock_guard lock(running.mutex);
      EXPECT_LT((running.poses[0].blade.tip - kTranslationMm / 1000.0).norm(), 1e-8);
      EXPECT_EQ(running.poses[0].device_stamp, timestamp_of(2.0));
    }
    // Forces, surfaces and STATUS come back in version 2 (the spec's GET_STATUS: no content).
    running.server.send_force(Vec3(0.5, 0, -1), timestamp_of(2.0));
    running.server.send_surface(encode_surface(std::vector<Triangle>{{0, 1, 2}}, {},
                                               std::vector<Vec3>(3, Vec3::Zero()), "Tissue", 1));
    send_bytes(client, spec_v2_message("GET_STATUS", "Query", 0, {}, {}));
    const auto replies = receive(client, 3);
    ASSERT_EQ(replies.size(), 3u);
    for (const auto& reply : replies) {
      EXPECT_EQ(get(reply, 0, 2), 2u);
      const auto events = read_all(reply);
      ASSERT_EQ(events.size(), 1u);
      ASSERT_TRUE(std::holds_alternative<Message>(events[0]));
      const Message& message = std::get<Message>(events[0]);
      EXPECT_FALSE(check_message(message));
      if (message.header.type == "SENSOR") {
        const auto force = decode_sensor(message);
        EXPECT_EQ(std::get<std::vector<double>>(force), (std::vector<double>{0.5, 0.0, -1.0}));
      } else if (message.header.type == "STATUS") {
        EXPECT_EQ(std::get<Status>(decode_status(message)).code, kStatusOk);
      } else {
        EXPECT_EQ(message.header.type, "POLYDATA");
        EXPECT_EQ(std::get<Surface>(decode_surface(message)).triangles.size(), 1u);
      }
    }
  }
  ASSERT_TRUE(eventually([&] { return !running.server.has_client(); }));
  // A version-1 client is answered in version 1 (it cannot say a long name: another server).
  ToolFrame frame;
  frame.rotation = kRotation;
  frame.translation = kTranslationMm / 1000.0;
  DeviceServer short_named("Scalpel");
  Socket short_client = connect_to("127.0.0.1", short_named.server.port(), 2.0);
  configure_stream(short_client);
  send_bytes(short_client, encode_transform(frame, "Scalpel", timestamp_of(5.0)));
  ASSERT_TRUE(eventually([&] { return short_named.pose_count() == 1; }));
  short_named.server.send_force(Vec3(0, 0, 1), timestamp_of(5.0));
  const auto replies = receive(short_client, 1);
  ASSERT_EQ(replies.size(), 1u);
  EXPECT_EQ(get(replies[0], 0, 2), 1u);
  EXPECT_EQ(replies[0].size(), kHeaderSize + get(replies[0], 42, 8));
}

}  // namespace
}  // namespace incise::igtl
