#pragma once
// OpenIGTLink header version 2 (protocol 3, 2017), read and written by incise's own code
// because Debian's libopenigtlink (1.11) predates it. From the protocol's description
// (openigtlink.org, "Version 3"; the header's V field is 2 for it):
//
//   body = extended header | content | metadata header | metadata
//   extended header, 12 bytes: uint16 its own size (>= 12; a larger one carries fields this
//     reader skips), uint16 the metadata header's size (2 + 8 n), uint32 the metadata's size
//     (its keys' and values' bytes), uint32 a message id;
//   metadata header: uint16 n, then n x (uint16 key size, uint16 value encoding (IANA
//     MIBenum), uint32 value size);
//   metadata: n x (key, value).
//
// All numbers are big-endian. The header's BODY_SIZE counts all four parts and its CRC-64
// covers all of them. The content is exactly a version-1 body of the message's type.

#include <cstdint>
#include <optional>
#include <span>
#include <variant>
#include <vector>

#include "incise/igtl/wire.hpp"

namespace incise::igtl {

inline constexpr std::size_t kExtendedHeaderSize = 12;
/// Most metadata entries a message may carry (Slicer and PLUS send a handful).
inline constexpr std::size_t kMaxMetadataEntries = 256;

/// Where a body's parts lie (header version 1: all of it is content).
struct BodyParts {
  std::size_t content_offset = 0;       ///< bytes into the body where the content starts
  std::size_t content_size = 0;         ///< the content's bytes
  std::uint32_t message_id = 0;         ///< the extended header's message id (0 for version 1)
  std::vector<MetadataEntry> metadata;  ///< version 2's metadata entries
};
/// The parts of `body`, sent with header version `version`. Every size read is checked
/// against the bytes present before use; a body whose parts do not add up is refused.
[[nodiscard]] std::variant<BodyParts, DropReason> parse_body(std::uint16_t version,
                                                             std::span<const std::uint8_t> body);

/// Sets `message`'s content_offset, content_size, message_id and metadata from its body (the
/// whole body is the content for header version 1). Every size read is checked against the
/// bytes present before use; a body whose parts do not add up is refused.
[[nodiscard]] std::optional<DropReason> split_body(Message& message);

/// `message` (a whole version-1 message, header and body, as the library packs it) in header
/// version `version`: unchanged for 1; for 2 its body wrapped with an extended header
/// carrying `message_id` and with `metadata`, and its header's version, body size and CRC
/// rewritten.
[[nodiscard]] std::vector<std::uint8_t> in_header_version(
    std::vector<std::uint8_t> message, std::uint16_t version, std::uint32_t message_id = 0,
    std::span<const MetadataEntry> metadata = {});

}  // namespace incise::igtl
