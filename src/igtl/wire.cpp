#include "incise/igtl/wire.hpp"

// OpenIGTLink's headers predate modern warnings; they are included as system headers.
#include <igtlMessageHeader.h>
#include <igtlPolyDataMessage.h>
#include <igtlSensorMessage.h>
#include <igtlStatusMessage.h>
#include <igtlTransformMessage.h>
#include <igtl_header.h>
#include <igtl_polydata.h>
#include <igtl_sensor.h>
#include <igtl_transform.h>
#include <igtl_util.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <tuple>
#include <unordered_map>

#include "incise/core/error.hpp"
#include "incise/igtl/extended_header.hpp"

namespace incise::igtl {
namespace {

constexpr std::array<std::string_view, kDropReasons> kDropNames = {
    "truncated",    "version",  "oversized",       "body_size",    "crc",
    "unknown_type", "bad_name", "unsupported",     "other_device", "not_finite",
    "not_rigid",    "stale",    "extended_header", "metadata"};

// The message types of OpenIGTLink version 2 (openigtlink.org/protocols/v2_header.html) and
// those protocol 3 added (COMMAND; VIDEO and VIDEOMETA of the video extension).
constexpr std::array<std::string_view, 21> kTypes = {
    "TRANSFORM", "POSITION", "IMAGE", "STATUS", "CAPABILITY", "SENSOR",  "POLYDATA",
    "STRING",    "POINT",    "TRAJ",  "TDATA",  "QTDATA",     "IMGMETA", "LBMETA",
    "COLORT",    "NDARRAY",  "BIND",  "QTRANS", "COMMAND",    "VIDEO",   "VIDEOMETA"};

std::vector<std::uint8_t> packed(::igtl::MessageBase& message) {
  message.Pack();
  const auto* begin = static_cast<const std::uint8_t*>(message.GetPackPointer());
  return {begin, begin + message.GetPackSize()};
}

void stamp(::igtl::MessageBase& message, std::uint64_t timestamp) {
  message.SetTimeStamp(static_cast<unsigned int>(timestamp >> 32),
                       static_cast<unsigned int>(timestamp & 0xffffffffu));
}

/// The library's typed message for a checked Message's content, or null when it does not
/// unpack. The library (1.11) reads version-1 messages only: it is handed the content under a
/// version-1 header with that content's size and CRC.
template <typename Typed>
typename Typed::Pointer unpack(const Message& message) {
  const std::span<const std::uint8_t> content = message.content();
  igtl_header raw{};
  std::memcpy(&raw, message.raw_header.data(), kHeaderSize);
  igtl_header_convert_byte_order(&raw);
  raw.version = kHeaderVersion1;
  raw.body_size = content.size();
  raw.crc = body_crc(content);
  igtl_header_convert_byte_order(&raw);
  auto header = ::igtl::MessageHeader::New();
  header->InitPack();
  std::memcpy(header->GetPackPointer(), &raw, kHeaderSize);
  header->Unpack();
  auto typed = Typed::New();
  typed->SetMessageHeader(header);
  typed->AllocatePack();
  if (static_cast<std::size_t>(typed->GetPackBodySize()) != content.size()) {
    return nullptr;
  }
  std::memcpy(typed->GetPackBodyPointer(), content.data(), content.size());
  const int status = typed->Unpack(1);
  if ((status & ::igtl::MessageHeader::UNPACK_BODY) == 0) {
    return nullptr;
  }
  return typed;
}

bool printable(std::string_view name) {
  return std::all_of(name.begin(), name.end(), [](char c) {
    return static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7f;
  });
}

// The metadata key a version-2 sender may carry a longer device name in.
constexpr std::string_view kDeviceNameKey = "DeviceName";
constexpr std::size_t kLongestDeviceName = 256;

std::string fixed_string(const char* bytes, std::size_t size) {
  return {bytes, strnlen(bytes, size)};
}

}  // namespace

std::string_view name_of(DropReason reason) {
  return kDropNames.at(static_cast<std::size_t>(reason));
}

double Header::seconds() const {
  return static_cast<double>(timestamp >> 32) +
         static_cast<double>(timestamp & 0xffffffffu) / 4294967296.0;
}

Header parse_header(std::span<const std::uint8_t, kHeaderSize> bytes) {
  static_assert(sizeof(igtl_header) == kHeaderSize);
  igtl_header raw{};
  std::memcpy(&raw, bytes.data(), kHeaderSize);
  igtl_header_convert_byte_order(&raw);
  Header header;
  header.version = raw.version;
  header.type = fixed_string(raw.name, IGTL_HEADER_TYPE_SIZE);
  header.device = fixed_string(raw.device_name, IGTL_HEADER_NAME_SIZE);
  header.timestamp = raw.timestamp;
  header.body_size = raw.body_size;
  header.crc = raw.crc;
  return header;
}

bool is_known_type(std::string_view type) {
  for (std::string_view prefix : {"GET_", "STT_", "STP_", "RTS_"}) {
    if (type.starts_with(prefix) && type.size() > prefix.size()) {
      type.remove_prefix(prefix.size());
      break;
    }
  }
  return std::find(kTypes.begin(), kTypes.end(), type) != kTypes.end();
}

std::uint64_t timestamp_of(double seconds) {
  if (!(seconds > 0.0) || !std::isfinite(seconds) || seconds >= 4294967296.0) {
    return 0;
  }
  const double whole = std::floor(seconds);
  const auto fraction = static_cast<std::uint64_t>((seconds - whole) * 4294967296.0);
  return (static_cast<std::uint64_t>(whole) << 32) | std::min<std::uint64_t>(fraction, 0xffffffffu);
}

std::uint64_t body_crc(std::span<const std::uint8_t> body) {
  return crc64(const_cast<std::uint8_t*>(body.data()), body.size(), 0ULL);
}

std::string Message::device_name() const {
  for (const MetadataEntry& entry : metadata) {
    if (entry.key == kDeviceNameKey) {
      return entry.value;
    }
  }
  return header.device;
}

std::optional<DropReason> check_message(const Message& message) {
  const Header& header = message.header;
  if (!is_known_type(header.type)) {
    return DropReason::kUnknownType;
  }
  if (header.device.empty() || !printable(header.device)) {
    return DropReason::kBadName;
  }
  if (message.body.size() != header.body_size) {
    return DropReason::kBodySize;
  }
  // The header's CRC-64 (ECMA-182) covers the whole body (for header version 2 the extended
  // header and metadata too); the library computes it.
  if (body_crc(message.body) != header.crc) {
    return DropReason::kCrc;
  }
  // The reader split the body; a message put together elsewhere is checked to agree.
  const auto parts = parse_body(header.version, message.body);
  if (const auto* reason = std::get_if<DropReason>(&parts)) {
    return *reason;
  }
  if (std::get<BodyParts>(parts).content_offset != message.content_offset ||
      std::get<BodyParts>(parts).content_size != message.content_size) {
    return DropReason::kExtendedHeader;
  }
  const std::string device = message.device_name();
  if (device.empty() || device.size() > kLongestDeviceName || !printable(device)) {
    return DropReason::kBadName;
  }
  return std::nullopt;
}

std::variant<ToolFrame, DropReason> decode_transform(const Message& message) {
  if (message.header.type != "TRANSFORM") {
    return DropReason::kUnsupported;
  }
  if (message.content().size() != IGTL_TRANSFORM_SIZE) {
    return DropReason::kBodySize;
  }
  const auto typed = unpack<::igtl::TransformMessage>(message);
  if (!typed) {
    return DropReason::kCrc;
  }
  ::igtl::Matrix4x4 matrix;
  typed->GetMatrix(matrix);
  ToolFrame frame;
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      frame.rotation(row, column) = matrix[row][column];
    }
    frame.translation[row] = matrix[row][3] / kWireUnitsPerMetre;
  }
  if (!frame.rotation.allFinite() || !frame.translation.allFinite()) {
    return DropReason::kNotFinite;
  }
  // Rigid within the float precision a device sends (about 1e-7) with a wide margin.
  const double orthogonality =
      (frame.rotation.transpose() * frame.rotation - Mat3::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality > 1e-3 || std::abs(frame.rotation.determinant() - 1.0) > 1e-3) {
    return DropReason::kNotRigid;
  }
  return frame;
}

std::variant<std::vector<double>, DropReason> decode_sensor(const Message& message) {
  if (message.header.type != "SENSOR") {
    return DropReason::kUnsupported;
  }
  // 10 bytes of sensor header (length, status, unit) and 8 per value.
  const auto content = message.content();
  if (content.size() < IGTL_SENSOR_HEADER_SIZE ||
      content.size() != IGTL_SENSOR_HEADER_SIZE + 8u * content[0]) {
    return DropReason::kBodySize;
  }
  const auto typed = unpack<::igtl::SensorMessage>(message);
  if (!typed) {
    return DropReason::kCrc;
  }
  std::vector<double> values(typed->GetLength());
  for (unsigned i = 0; i < values.size(); ++i) {
    values[i] = typed->GetValue(i);
    if (!std::isfinite(values[i])) {
      return DropReason::kNotFinite;
    }
  }
  return values;
}

std::variant<Status, DropReason> decode_status(const Message& message) {
  if (message.header.type != "STATUS") {
    return DropReason::kUnsupported;
  }
  // code (2), subcode (8), error name (20), then a null-terminated text.
  if (message.content().size() < 31 || message.content().back() != 0) {
    return DropReason::kBodySize;
  }
  const auto typed = unpack<::igtl::StatusMessage>(message);
  if (!typed) {
    return DropReason::kCrc;
  }
  return Status{typed->GetCode(), fixed_string(typed->GetErrorName(), 20),
                std::string(typed->GetStatusString())};
}

std::vector<std::uint8_t> encode_transform(const ToolFrame& frame, const std::string& device,
                                           std::uint64_t timestamp) {
  auto message = ::igtl::TransformMessage::New();
  message->SetDeviceName(device.c_str());
  ::igtl::Matrix4x4 matrix;
  ::igtl::IdentityMatrix(matrix);
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      matrix[row][column] = static_cast<float>(frame.rotation(row, column));
    }
    matrix[row][3] = static_cast<float>(frame.translation[row] * kWireUnitsPerMetre);
  }
  message->SetMatrix(matrix);
  stamp(*message, timestamp);
  return packed(*message);
}

std::vector<std::uint8_t> encode_force(const Vec3& force, const std::string& device,
                                       std::uint64_t timestamp) {
  auto message = ::igtl::SensorMessage::New();
  message->SetDeviceName(device.c_str());
  message->SetLength(3);
  for (unsigned i = 0; i < 3; ++i) {
    message->SetValue(i, force[static_cast<int>(i)]);
  }
  auto unit = ::igtl::Unit::New();
  unit->Init();
  unit->SetPrefix(::igtl::Unit::SI_PREFIX_NONE);
  unit->Append(::igtl::Unit::SI_DERIVED_NEWTON, 1);
  message->SetUnit(unit);
  stamp(*message, timestamp);
  return packed(*message);
}

std::vector<std::uint8_t> encode_status(int code, const std::string& error_name,
                                        const std::string& text, const std::string& device) {
  auto message = ::igtl::StatusMessage::New();
  message->SetDeviceName(device.c_str());
  message->SetCode(code);
  message->SetSubCode(0);
  message->SetErrorName(error_name.substr(0, 19).c_str());
  message->SetStatusString(text.c_str());
  return packed(*message);
}

std::vector<std::uint8_t> encode_surface(std::span<const Triangle> triangles,
                                         std::span<const std::uint8_t> on_cut,
                                         std::span<const Vec3> positions, const std::string& device,
                                         std::uint64_t timestamp) {
  auto points = ::igtl::PolyDataPointArray::New();
  auto polygons = ::igtl::PolyDataCellArray::New();
  std::unordered_map<VertexId, igtlUint32> compact;
  compact.reserve(triangles.size());
  // Per point: its triangles, and how many of them a cut opened.
  std::vector<std::array<std::uint32_t, 2>> uses;
  uses.reserve(triangles.size());
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const bool cut = i < on_cut.size() && on_cut[i] != 0;
    igtlUint32 cell[3];
    for (int corner = 0; corner < 3; ++corner) {
      const VertexId vertex = triangles[i][static_cast<std::size_t>(corner)];
      const auto [slot, added] =
          compact.try_emplace(vertex, static_cast<igtlUint32>(compact.size()));
      if (added) {
        const Vec3 p = positions[static_cast<std::size_t>(vertex)] * kWireUnitsPerMetre;
        points->AddPoint(static_cast<float>(p.x()), static_cast<float>(p.y()),
                         static_cast<float>(p.z()));
        uses.push_back({0, 0});
      }
      cell[corner] = slot->second;
      ++uses[slot->second][0];
      uses[slot->second][1] += cut ? 1 : 0;
    }
    polygons->AddCell(3, cell);
  }
  // The marks go out as a point scalar: the reference C reader (igtl_polydata.c) sizes point
  // attributes right but reads a cell scalar as 9 components, past the message (Slicer's side
  // included). Each point carries the share of its triangles that a cut opened: 1 inside the
  // wound, 0 on the untouched skin, between on the wound's rim (the surface stays one closed
  // mesh, so a point there belongs to both).
  std::vector<float> cut_share(uses.size());
  for (std::size_t p = 0; p < uses.size(); ++p) {
    cut_share[p] = static_cast<float>(uses[p][1]) / static_cast<float>(uses[p][0]);
  }
  auto message = ::igtl::PolyDataMessage::New();
  message->SetDeviceName(device.c_str());
  message->SetPoints(points);
  message->SetPolygons(polygons);
  auto attribute = ::igtl::PolyDataAttribute::New();
  attribute->SetType(::igtl::PolyDataAttribute::POINT_SCALAR);
  attribute->SetName("CutFace");
  attribute->SetSize(static_cast<igtlUint32>(cut_share.size()));
  if (!cut_share.empty()) {
    attribute->SetData(cut_share.data());
  }
  message->AddAttribute(attribute);
  stamp(*message, timestamp);
  return packed(*message);
}

namespace {

/// Big-endian reads with bounds checks, for the POLYDATA decoder below.
class BodyCursor {
 public:
  explicit BodyCursor(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  [[nodiscard]] bool has(std::uint64_t count) const { return count <= bytes_.size() - at_; }
  std::uint32_t u32() {
    std::uint32_t value = 0;
    for (int i = 0; i < 4; ++i) {
      value = (value << 8) | bytes_[at_++];
    }
    return value;
  }
  std::uint8_t u8() { return bytes_[at_++]; }
  float f32() { return std::bit_cast<float>(u32()); }
  void skip(std::size_t count) { at_ += count; }
  [[nodiscard]] std::size_t at() const { return at_; }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t at_ = 0;
};

}  // namespace

// Written against the protocol's POLYDATA layout rather than through the library: its 1.11
// unpacker reads cell attributes as tensors, past its buffer (valgrind), and trusts every
// count it reads. Attribute sizes follow the protocol (scalar: its components, normal and
// vector: 3, tensor: 9, per item). Here each count is checked against the bytes present before use.
std::variant<Surface, DropReason> decode_surface(const Message& message) {
  if (message.header.type != "POLYDATA") {
    return DropReason::kUnsupported;
  }
  BodyCursor cursor(message.content());
  if (!cursor.has(40)) {
    return DropReason::kBodySize;
  }
  std::array<std::uint32_t, 10> counts{};
  for (std::uint32_t& count : counts) {
    count = cursor.u32();
  }
  const auto [points, vertices_size, lines_size, polygons, polygons_size, strips_size, attributes] =
      std::tuple{counts[0], counts[2], counts[4], counts[5], counts[6], counts[8], counts[9]};
  Surface surface;
  if (!cursor.has(12ULL * points)) {
    return DropReason::kBodySize;
  }
  surface.points.reserve(points);
  for (std::uint32_t i = 0; i < points; ++i) {
    const float x = cursor.f32();
    const float y = cursor.f32();
    const float z = cursor.f32();
    surface.points.emplace_back(Vec3(x, y, z) / kWireUnitsPerMetre);
  }
  if (!cursor.has(std::uint64_t{vertices_size} + lines_size)) {
    return DropReason::kBodySize;
  }
  cursor.skip(std::size_t{vertices_size} + lines_size);
  if (!cursor.has(polygons_size) || polygons_size != 16ULL * polygons) {
    return DropReason::kBodySize;  // incise sends triangles only
  }
  for (std::uint32_t i = 0; i < polygons; ++i) {
    Triangle triangle{};
    if (cursor.u32() != 3) {
      return DropReason::kBodySize;
    }
    for (VertexId& corner : triangle) {
      const std::uint32_t id = cursor.u32();
      if (id >= points) {
        return DropReason::kBodySize;
      }
      corner = static_cast<VertexId>(id);
    }
    surface.triangles.push_back(triangle);
  }
  if (!cursor.has(strips_size) || !cursor.has(strips_size + 6ULL * attributes)) {
    return DropReason::kBodySize;
  }
  cursor.skip(strips_size);
  struct AttributeHeader {
    std::uint8_t type;
    std::uint8_t components;
    std::uint32_t size;
  };
  std::vector<AttributeHeader> headers;
  for (std::uint32_t i = 0; i < attributes; ++i) {
    const std::uint8_t type = cursor.u8();
    const std::uint8_t components = cursor.u8();
    headers.push_back({type, components, cursor.u32()});
  }
  std::vector<std::string> names;
  const std::size_t names_start = cursor.at();
  for (std::uint32_t i = 0; i < attributes; ++i) {
    std::string name;
    while (true) {
      if (!cursor.has(1)) {
        return DropReason::kBodySize;
      }
      const auto c = static_cast<char>(cursor.u8());
      if (c == '\0') {
        break;
      }
      name.push_back(c);
    }
    names.push_back(name);
  }
  if ((cursor.at() - names_start) % 2 == 1 && cursor.has(1)) {
    cursor.skip(1);  // names are padded to an even length
  }
  for (std::uint32_t i = 0; i < attributes; ++i) {
    const AttributeHeader& header = headers[i];
    const std::uint64_t per_item = (header.type & 0x0f) == 0   ? header.components
                                   : (header.type & 0x0f) == 3 ? 9
                                                               : 3;
    const std::uint64_t values = per_item * header.size;
    if (!cursor.has(4 * values)) {
      return DropReason::kBodySize;
    }
    const bool cut_scalar = names[i] == "CutFace" && header.type == 0x00 &&
                            header.components == 1 && header.size == surface.points.size();
    for (std::uint64_t v = 0; v < values; ++v) {
      const float value = cursor.f32();
      if (cut_scalar) {
        surface.cut_share.push_back(value);
      }
    }
  }
  return surface;
}

void MessageReader::feed(std::span<const std::uint8_t> bytes) {
  if (fatal_) {
    return;
  }
  // Discard what a dropped message's body still owes before keeping anything.
  const std::size_t skipped =
      static_cast<std::size_t>(std::min<std::uint64_t>(skip_, bytes.size()));
  skip_ -= skipped;
  bytes = bytes.subspan(skipped);
  buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start_));
  start_ = 0;
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<MessageReader::Event> MessageReader::next() {
  if (fatal_ || skip_ > 0 || buffer_.size() - start_ < kHeaderSize) {
    return std::nullopt;
  }
  Message message;
  std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(start_), kHeaderSize,
              message.raw_header.begin());
  message.header = parse_header(message.raw_header);
  const Header& header = message.header;
  if (header.body_size > kMaxBodySize) {
    fatal_ = true;
    buffer_.clear();
    start_ = 0;
    return Drop{DropReason::kOversized, header};
  }
  const std::size_t available = buffer_.size() - start_ - kHeaderSize;
  const auto body_size = static_cast<std::size_t>(header.body_size);
  const bool bad_version = header.version != kHeaderVersion1 && header.version != kHeaderVersion2;
  const bool unknown = !is_known_type(header.type);
  if (bad_version || unknown) {
    // Skip the body as it arrives: the stream stays aligned if the size was honest.
    const std::size_t present = std::min(available, body_size);
    start_ += kHeaderSize + present;
    skip_ = body_size - present;
    return Drop{bad_version ? DropReason::kVersion : DropReason::kUnknownType, header};
  }
  if (available < body_size) {
    return std::nullopt;
  }
  const auto body_begin = buffer_.begin() + static_cast<std::ptrdiff_t>(start_ + kHeaderSize);
  message.body.assign(body_begin, body_begin + static_cast<std::ptrdiff_t>(body_size));
  start_ += kHeaderSize + body_size;
  if (start_ == buffer_.size()) {
    buffer_.clear();
    start_ = 0;
  }
  if (const auto reason = split_body(message)) {
    // A body whose parts do not add up: damaged on the way (the CRC says so) or sent so.
    return Drop{body_crc(message.body) != header.crc ? DropReason::kCrc : *reason, header};
  }
  return message;
}

}  // namespace incise::igtl
