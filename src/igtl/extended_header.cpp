#include "incise/igtl/extended_header.hpp"

#include <string>

#include "incise/core/error.hpp"

namespace incise::igtl {
namespace {

std::uint64_t read_big_endian(std::span<const std::uint8_t> bytes, std::size_t at,
                              std::size_t size) {
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < size; ++i) {
    value = (value << 8) | bytes[at + i];
  }
  return value;
}

void write_big_endian(std::uint8_t* to, std::uint64_t value, std::size_t size) {
  for (std::size_t i = size; i-- > 0;) {
    to[i] = static_cast<std::uint8_t>(value & 0xffu);
    value >>= 8;
  }
}

void append_big_endian(std::vector<std::uint8_t>& to, std::uint64_t value, std::size_t size) {
  to.resize(to.size() + size);
  write_big_endian(to.data() + to.size() - size, value, size);
}

// Offsets of the header's fields (header.md): V, TYPE, DEVICE_NAME, TIME_STAMP, BODY_SIZE, CRC.
constexpr std::size_t kBodySizeAt = 42;
constexpr std::size_t kCrcAt = 50;

}  // namespace

std::variant<BodyParts, DropReason> parse_body(std::uint16_t version,
                                               std::span<const std::uint8_t> body) {
  if (version != kHeaderVersion2) {
    return BodyParts{0, body.size(), 0, {}};
  }
  if (body.size() < kExtendedHeaderSize) {
    return DropReason::kExtendedHeader;
  }
  const std::uint64_t extended_size = read_big_endian(body, 0, 2);
  const std::uint64_t metadata_header_size = read_big_endian(body, 2, 2);
  const std::uint64_t metadata_size = read_big_endian(body, 4, 4);
  const std::uint32_t message_id = static_cast<std::uint32_t>(read_big_endian(body, 8, 4));
  // Sizes as 64-bit sums of 16- and 32-bit fields: none can overflow.
  if (extended_size < kExtendedHeaderSize ||
      extended_size + metadata_header_size + metadata_size > body.size()) {
    return DropReason::kExtendedHeader;
  }
  const std::size_t content_size =
      body.size() - static_cast<std::size_t>(extended_size + metadata_header_size + metadata_size);
  std::size_t at = static_cast<std::size_t>(extended_size) + content_size;
  std::vector<MetadataEntry> metadata;
  if (metadata_header_size > 0) {
    // The metadata header begins with its entry count and holds 8 bytes per entry.
    if (metadata_header_size < 2) {
      return DropReason::kMetadata;
    }
    const std::uint64_t count = read_big_endian(body, at, 2);
    if (count > kMaxMetadataEntries || metadata_header_size != 2 + 8 * count) {
      return DropReason::kMetadata;
    }
    struct Sizes {
      std::uint64_t key, value;
      std::uint16_t encoding;
    };
    std::vector<Sizes> sizes;
    std::uint64_t total = 0;
    for (std::uint64_t i = 0; i < count; ++i) {
      const std::size_t entry = at + 2 + 8 * static_cast<std::size_t>(i);
      Sizes s{read_big_endian(body, entry, 2), read_big_endian(body, entry + 4, 4),
              static_cast<std::uint16_t>(read_big_endian(body, entry + 2, 2))};
      total += s.key + s.value;
      sizes.push_back(s);
    }
    if (total != metadata_size) {
      return DropReason::kMetadata;
    }
    at += static_cast<std::size_t>(metadata_header_size);
    for (const Sizes& s : sizes) {
      const auto* begin = reinterpret_cast<const char*>(body.data() + at);
      MetadataEntry entry;
      entry.key.assign(begin, static_cast<std::size_t>(s.key));
      entry.value.assign(begin + s.key, static_cast<std::size_t>(s.value));
      entry.encoding = s.encoding;
      at += static_cast<std::size_t>(s.key + s.value);
      metadata.push_back(std::move(entry));
    }
  } else if (metadata_size != 0) {
    return DropReason::kMetadata;  // metadata without a header to say what it holds
  }
  return BodyParts{static_cast<std::size_t>(extended_size), content_size, message_id,
                   std::move(metadata)};
}

std::optional<DropReason> split_body(Message& message) {
  auto parts = parse_body(message.header.version, message.body);
  if (const auto* reason = std::get_if<DropReason>(&parts)) {
    return *reason;
  }
  BodyParts& split = std::get<BodyParts>(parts);
  message.content_offset = split.content_offset;
  message.content_size = split.content_size;
  message.message_id = split.message_id;
  message.metadata = std::move(split.metadata);
  return std::nullopt;
}

std::vector<std::uint8_t> in_header_version(std::vector<std::uint8_t> message,
                                            std::uint16_t version, std::uint32_t message_id,
                                            std::span<const MetadataEntry> metadata) {
  INCISE_ASSERT(message.size() >= kHeaderSize, "a whole message to re-head");
  if (version != kHeaderVersion2) {
    return message;
  }
  std::uint64_t metadata_size = 0;
  for (const MetadataEntry& entry : metadata) {
    metadata_size += entry.key.size() + entry.value.size();
  }
  std::vector<std::uint8_t> wrapped(message.begin(), message.begin() + kHeaderSize);
  const std::size_t content_size = message.size() - kHeaderSize;
  wrapped.reserve(kHeaderSize + kExtendedHeaderSize + content_size + 2 + 8 * metadata.size() +
                  static_cast<std::size_t>(metadata_size));
  append_big_endian(wrapped, kExtendedHeaderSize, 2);
  append_big_endian(wrapped, 2 + 8 * metadata.size(), 2);
  append_big_endian(wrapped, metadata_size, 4);
  append_big_endian(wrapped, message_id, 4);
  wrapped.insert(wrapped.end(), message.begin() + kHeaderSize, message.end());
  append_big_endian(wrapped, metadata.size(), 2);
  for (const MetadataEntry& entry : metadata) {
    append_big_endian(wrapped, entry.key.size(), 2);
    append_big_endian(wrapped, entry.encoding, 2);
    append_big_endian(wrapped, entry.value.size(), 4);
  }
  for (const MetadataEntry& entry : metadata) {
    wrapped.insert(wrapped.end(), entry.key.begin(), entry.key.end());
    wrapped.insert(wrapped.end(), entry.value.begin(), entry.value.end());
  }
  const std::span<const std::uint8_t> body = std::span(wrapped).subspan(kHeaderSize);
  write_big_endian(wrapped.data(), version, 2);
  write_big_endian(wrapped.data() + kBodySizeAt, body.size(), 8);
  write_big_endian(wrapped.data() + kCrcAt, body_crc(body), 8);
  return wrapped;
}

}  // namespace incise::igtl
