#pragma once
// OpenIGTLink on the wire: the messages incise serve and incise device exchange, encoded and
// decoded through the OpenIGTLink library (Debian's libopenigtlink, protocol version 2 with
// version-1 headers), and checked before anything is trusted: header version, size limits,
// CRC, the body size for the type, finite numbers, a pose that is a rigid transform.
//
// Header version 2 (protocol 3, 2017: what 3D Slicer's OpenIGTLinkIF and PLUS send) is read
// and written by incise's own code (extended_header.hpp), since Debian's library (1.11)
// predates it: its body is an extended header, the content (a version-1 body), a metadata
// header and the metadata, with the CRC over all of them.
//
// Units on the wire are millimetres, as 3D Slicer and the PLUS toolkit use; incise's own
// types stay in metres and the conversion happens here only.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "incise/cut/blade.hpp"

namespace incise::igtl {

inline constexpr std::size_t kHeaderSize = 58;
inline constexpr std::uint16_t kHeaderVersion1 = 1;   ///< protocols 1 and 2
inline constexpr std::uint16_t kHeaderVersion2 = 2;   ///< protocol 3: extended header, metadata
inline constexpr double kWireUnitsPerMetre = 1000.0;  ///< mm per m
/// Largest body a peer may send us: a TRANSFORM is 48 bytes; anything larger than this is a
/// broken or hostile stream (the connection cannot be resynchronised and is closed).
inline constexpr std::uint64_t kMaxBodySize = 16u << 20;

/// Why a message was dropped (the report counts each).
enum class DropReason : std::uint8_t {
  kTruncated,       ///< the stream ended inside a message
  kVersion,         ///< header version other than 1 or 2
  kOversized,       ///< body larger than kMaxBodySize (the connection is closed)
  kBodySize,        ///< wrong body size for its type
  kCrc,             ///< the body's CRC-64 does not match the header's
  kUnknownType,     ///< not an OpenIGTLink message type
  kBadName,         ///< empty device name, or a name with control characters
  kUnsupported,     ///< a valid type incise does not take (skipped)
  kOtherDevice,     ///< a TRANSFORM for another device
  kNotFinite,       ///< NaN or infinity in the numbers
  kNotRigid,        ///< a pose whose rotation is not orthonormal with determinant +1
  kStale,           ///< older than the newest pose already taken
  kExtendedHeader,  ///< header version 2: extended header sizes that do not fit the body
  kMetadata,        ///< header version 2: metadata entries that do not fit, or too many
  kCount
};
inline constexpr std::size_t kDropReasons = static_cast<std::size_t>(DropReason::kCount);
[[nodiscard]] std::string_view name_of(DropReason reason);

/// An OpenIGTLink header (58 bytes on the wire).
struct Header {
  std::uint16_t version = 0;    ///< header version: 1, or 2 for protocol 3's extended header
  std::string type;             ///< e.g. "TRANSFORM"
  std::string device;           ///< e.g. "Scalpel"
  std::uint64_t timestamp = 0;  ///< seconds << 32 | fraction of a second (0: none)
  std::uint64_t body_size = 0;  ///< bytes after the header
  std::uint64_t crc = 0;        ///< CRC-64 of the body
  /// The time stamp in seconds (0 when none).
  [[nodiscard]] double seconds() const;
};

/// One metadata entry of a header-version-2 message (its value in the encoding named, an
/// IANA MIBenum: 3 is US-ASCII, 106 UTF-8).
struct MetadataEntry {
  std::string key;             ///< the entry's key
  std::uint16_t encoding = 3;  ///< the value's encoding (IANA MIBenum)
  std::string value;           ///< the value's bytes
  /// Equal keys, encodings and values.
  bool operator==(const MetadataEntry&) const = default;
};

/// A complete message as read: its header, parsed and raw, and its body split into parts.
struct Message {
  Header header;                                       ///< parsed
  std::array<std::uint8_t, kHeaderSize> raw_header{};  ///< as on the wire
  /// The body as on the wire (header version 2: extended header, content, metadata).
  std::vector<std::uint8_t> body;
  /// Where the content (the message type's own bytes) lies in `body`: all of it for header
  /// version 1.
  std::size_t content_offset = 0;
  std::size_t content_size = 0;         ///< the content's bytes
  std::uint32_t message_id = 0;         ///< header version 2's message id (0 otherwise)
  std::vector<MetadataEntry> metadata;  ///< header version 2's metadata
  /// The content's bytes.
  [[nodiscard]] std::span<const std::uint8_t> content() const {
    return std::span(body).subspan(content_offset, content_size);
  }
  /// The device's name: the metadata's "DeviceName" where a version-2 sender put one there
  /// (names longer than the header's 20 characters), else the header's.
  [[nodiscard]] std::string device_name() const;
};

/// Parses the 58 header bytes (big-endian on the wire). Never fails: checks come after.
[[nodiscard]] Header parse_header(std::span<const std::uint8_t, kHeaderSize> bytes);
/// Whether `type` is a message type of the OpenIGTLink protocol (including GET_, STT_, STP_
/// and RTS_ queries).
[[nodiscard]] bool is_known_type(std::string_view type);
/// The time stamp of `seconds` since the epoch of the caller's clock.
[[nodiscard]] std::uint64_t timestamp_of(double seconds);

/// The CRC-64 (ECMA-182) OpenIGTLink puts in a header for `body`.
[[nodiscard]] std::uint64_t body_crc(std::span<const std::uint8_t> body);

/// A complete message's header-level checks: name, known type, CRC, and for header version 2
/// the extended header and metadata (see split_body).
[[nodiscard]] std::optional<DropReason> check_message(const Message& message);

/// A TRANSFORM's tool frame (m): a complete, checked message of that type.
[[nodiscard]] std::variant<ToolFrame, DropReason> decode_transform(const Message& message);
/// A SENSOR's values, checked finite.
[[nodiscard]] std::variant<std::vector<double>, DropReason> decode_sensor(const Message& message);
/// A STATUS's code and text.
struct Status {
  int code = 0;            ///< the protocol's status code (1: OK)
  std::string error_name;  ///< up to 20 characters
  std::string text;        ///< the message
};
[[nodiscard]] std::variant<Status, DropReason> decode_status(const Message& message);

[[nodiscard]] std::vector<std::uint8_t> encode_transform(const ToolFrame& frame,
                                                         const std::string& device,
                                                         std::uint64_t timestamp);
/// A force (N) as a SENSOR of three values with the unit newton.
[[nodiscard]] std::vector<std::uint8_t> encode_force(const Vec3& force, const std::string& device,
                                                     std::uint64_t timestamp);
inline constexpr int kStatusOk = 1;
inline constexpr int kStatusBusy = 6;
inline constexpr int kStatusChecksum = 9;
inline constexpr int kStatusUnknownInstruction = 12;
inline constexpr int kStatusShutDown = 19;
[[nodiscard]] std::vector<std::uint8_t> encode_status(int code, const std::string& error_name,
                                                      const std::string& text,
                                                      const std::string& device);
/// A triangle surface (vertex ids into `positions`, m) as POLYDATA: only the vertices the
/// triangles use, in mm, with the point scalar "CutFace": the share of a point's triangles
/// that a cut opened (1 in the wound, 0 on untouched skin, between on the wound's rim). A
/// point scalar because the reference C reader misreads cell scalars.
[[nodiscard]] std::vector<std::uint8_t> encode_surface(std::span<const Triangle> triangles,
                                                       std::span<const std::uint8_t> on_cut,
                                                       std::span<const Vec3> positions,
                                                       const std::string& device,
                                                       std::uint64_t timestamp);
/// A decoded POLYDATA (for tests and clients): points (m), triangles, the CutFace point
/// scalar (empty when the message has none).
struct Surface {
  std::vector<Vec3> points;         ///< m
  std::vector<Triangle> triangles;  ///< indices into points
  std::vector<float> cut_share;     ///< per point, 0 to 1
};
[[nodiscard]] std::variant<Surface, DropReason> decode_surface(const Message& message);

/// Splits a byte stream into messages. Incomplete messages wait for more bytes; a header
/// with a bad version or an unknown type drops its message (its body is skipped); a body
/// size beyond kMaxBodySize is fatal (the stream cannot be trusted to resynchronise).
class MessageReader {
 public:
  /// A message the reader refused, and why.
  struct Drop {
    DropReason reason;  ///< why
    Header header;      ///< its header
  };
  /// What next() gives: a message or a drop.
  using Event = std::variant<Message, Drop>;

  /// Appends bytes from the stream.
  void feed(std::span<const std::uint8_t> bytes);
  /// The next complete message or drop, or nothing until more bytes come.
  [[nodiscard]] std::optional<Event> next();
  /// The stream broke beyond repair (an oversized body): close the connection.
  [[nodiscard]] bool fatal() const { return fatal_; }
  /// Bytes of an incomplete message are waiting (at the end of a stream: truncated).
  [[nodiscard]] bool partial() const { return buffer_.size() > start_ || skip_ > 0; }

 private:
  std::vector<std::uint8_t> buffer_;
  std::size_t start_ = 0;   ///< consumed bytes at the front of buffer_
  std::uint64_t skip_ = 0;  ///< body bytes of a dropped message still to discard
  bool fatal_ = false;
};

}  // namespace incise::igtl
