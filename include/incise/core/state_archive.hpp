#pragma once
// Binary state for checkpoints: what a component writes with StateWriter it reads back in the
// same order with StateReader. Values are raw bytes of the host (a checkpoint resumes on the
// machine kind that wrote it); every read is bounds-checked, so a truncated or corrupted
// checkpoint gives an InputError naming what was being read and where, never a crash or an
// allocation sized by a corrupted count.

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "incise/core/error.hpp"

namespace incise {

/// Types saved as their bytes: no pointers and no heap memory inside (numbers, fixed-size
/// Eigen types, and structs of those).
template <typename T>
concept RawState = std::is_standard_layout_v<T> && !std::is_pointer_v<T>;

/// Writes a checkpoint's state as bytes: values, lists, texts and section tags, in the order
/// StateReader reads them back.
class StateWriter {
 public:
  /// One value, as its bytes.
  template <RawState T>
  void value(const T& v) {
    const auto* bytes = reinterpret_cast<const char*>(&v);
    buffer_.append(bytes, sizeof(T));
  }
  /// A list: its length, then its values.
  template <RawState T>
  void values(const std::vector<T>& v) {
    value<std::uint64_t>(v.size());
    if (!v.empty()) {
      buffer_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
    }
  }
  /// A list of lists.
  template <RawState T>
  void nested(const std::vector<std::vector<T>>& v) {
    value<std::uint64_t>(v.size());
    for (const auto& inner : v) {
      values(inner);
    }
  }
  /// A text: its length, then its bytes.
  void text(std::string_view s) {
    value<std::uint64_t>(s.size());
    buffer_.append(s);
  }
  /// A name that the reader checks, so parts read back in a different order are caught.
  void tag(std::string_view name) { text(name); }
  /// Everything written so far.
  [[nodiscard]] const std::string& bytes() const { return buffer_; }

 private:
  std::string buffer_;
};

/// Reads what StateWriter wrote, checking every length against the bytes left and every tag:
/// a corrupt or foreign checkpoint fails with an InputError naming the byte and the part.
class StateReader {
 public:
  /// `source` names the checkpoint in errors.
  StateReader(std::string_view bytes, std::string source)
      : bytes_(bytes), source_(std::move(source)) {}

  /// One value; `what` names it in errors.
  template <RawState T>
  T value(const char* what) {
    need(sizeof(T), what);
    if constexpr (std::is_same_v<T, bool>) {
      // A bool's byte other than 0 or 1 is no bool: loading it would be undefined behaviour.
      const auto byte = static_cast<unsigned char>(bytes_[offset_]);
      if (byte > 1) {
        fail(what, "holds " + std::to_string(byte) + " where a yes/no value (0 or 1) belongs");
      }
      ++offset_;
      return byte == 1;
    }
    T v;
    std::memcpy(static_cast<void*>(&v), bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return v;
  }
  /// A list.
  template <RawState T>
  std::vector<T> values(const char* what) {
    const auto count = value<std::uint64_t>(what);
    // The count is checked against the bytes left before anything is allocated.
    if (count > (bytes_.size() - offset_) / (sizeof(T) == 0 ? 1 : sizeof(T))) {
      fail(what, "claims " + std::to_string(count) + " entries, more than the file holds");
    }
    std::vector<T> v(static_cast<std::size_t>(count));
    if (count > 0) {
      std::memcpy(static_cast<void*>(v.data()), bytes_.data() + offset_, v.size() * sizeof(T));
      offset_ += v.size() * sizeof(T);
    }
    return v;
  }
  /// A list of lists.
  template <RawState T>
  std::vector<std::vector<T>> nested(const char* what) {
    const auto count = value<std::uint64_t>(what);
    if (count > (bytes_.size() - offset_) / sizeof(std::uint64_t)) {
      fail(what, "claims " + std::to_string(count) + " lists, more than the file holds");
    }
    std::vector<std::vector<T>> v(static_cast<std::size_t>(count));
    for (auto& inner : v) {
      inner = values<T>(what);
    }
    return v;
  }
  /// A text.
  std::string text(const char* what) {
    const auto size = value<std::uint64_t>(what);
    need(size, what);
    std::string s(bytes_.substr(offset_, static_cast<std::size_t>(size)));
    offset_ += static_cast<std::size_t>(size);
    return s;
  }
  /// Checks that the next section is `name`.
  void tag(std::string_view name) {
    const std::string found = text("a section name");
    if (found != name) {
      fail("a section name", "expected '" + std::string(name) + "', found '" + found +
                                 "' (written by another scene or another version?)");
    }
  }
  /// Throws the reader's error for a value that was read but makes no sense.
  [[noreturn]] void fail(const char* what, const std::string& problem) const {
    throw InputError(
        source_, 0,
        "checkpoint corrupt at byte " + std::to_string(offset_) + " (" + what + "): " + problem);
  }
  /// Whether every byte was read.
  [[nodiscard]] bool at_end() const { return offset_ == bytes_.size(); }

 private:
  void need(std::uint64_t size, const char* what) const {
    if (size > bytes_.size() - offset_) {
      throw InputError(
          source_, 0,
          "checkpoint truncated at byte " + std::to_string(offset_) + " while reading " + what);
    }
  }
  std::string_view bytes_;
  std::string source_;
  std::size_t offset_ = 0;
};

}  // namespace incise
