#pragma once
// A whole input file in memory with a cursor that knows its line number, so every reader can
// say exactly where a file is wrong. Private to the io module.

#include <bit>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "incise/core/error.hpp"

namespace incise::io_detail {

class Source {
 public:
  /// Reads the whole file; throws InputError if it cannot be read.
  static Source open(const std::filesystem::path& path);
  Source(std::string name, std::string bytes) : name_(std::move(name)), bytes_(std::move(bytes)) {}

  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] std::string_view bytes() const { return bytes_; }
  [[nodiscard]] std::size_t offset() const { return offset_; }
  [[nodiscard]] std::size_t line() const { return line_; }
  [[nodiscard]] bool at_end() const { return offset_ >= bytes_.size(); }
  /// Moves the cursor (recounting lines from the start: use sparingly).
  void seek(std::size_t offset);

  /// Character that starts a comment running to the end of the line (0 for none).
  void set_comment_char(char comment) { comment_ = comment; }

  /// Skips whitespace and comments; returns the next token, empty at end of file.
  std::string_view next_token();
  /// As next_token but throws "unexpected end of file while reading <what>" at end of file.
  std::string_view token(const char* what);
  [[nodiscard]] std::string_view peek_token();
  /// Skips whitespace and comments; true if a token follows on the current line.
  bool token_on_this_line();
  /// The rest of the current line (without the newline), and moves past it.
  std::string_view rest_of_line();
  void skip_line() { (void)rest_of_line(); }

  long long integer(const char* what);
  double real(const char* what);
  /// A non-negative count no larger than `limit`.
  std::size_t count(const char* what, std::size_t limit);
  void expect(std::string_view keyword);

  /// Refuses, before anything is sized by it, a declared count of `values` that the bytes
  /// left cannot hold: in text each value takes a character and a separator, in binary
  /// `bytes_per_value` (0: text). A header claiming 10^9 values in a 1 KB file fails here.
  void require_room(std::size_t values, std::size_t bytes_per_value, const char* what) const;
  /// Whether `bytes` of text can hold `values` whitespace-separated values (a character and a
  /// separator each): the bound require_room applies to text.
  static bool text_can_hold(std::size_t values, std::size_t bytes) {
    return values == 0 || 2 * values - 1 <= bytes;
  }

  /// Reads `n` raw bytes; throws if the file ends first.
  void read_bytes(void* destination, std::size_t n, const char* what);
  template <typename T>
  T binary(bool swap_bytes, const char* what) {
    T value;
    read_bytes(&value, sizeof(T), what);
    if (swap_bytes) {
      value = byte_swapped(value);
    }
    return value;
  }
  /// Bytes left from the cursor.
  [[nodiscard]] std::size_t remaining() const {
    return offset_ < bytes_.size() ? bytes_.size() - offset_ : 0;
  }

  [[noreturn]] void fail(const std::string& message) const;
  /// For readers that do not advance the cursor (XML): fail() then names no line.
  void disable_line_numbers() { line_numbers_ = false; }
  /// Failure not tied to a line (binary data, whole-file problems).
  [[noreturn]] void fail_without_line(const std::string& message) const;

  template <typename T>
  static T byte_swapped(T value) {
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) {
      std::swap(raw[i], raw[sizeof(T) - 1 - i]);
    }
    std::memcpy(&value, raw, sizeof(T));
    return value;
  }

 private:
  void skip_space_and_comments();

  std::string name_;
  std::string bytes_;
  std::size_t offset_ = 0;
  std::size_t line_ = 1;
  char comment_ = 0;
  bool line_numbers_ = true;
};

/// Parses a whole token as a number; false on garbage, overflow or trailing characters.
bool parse_integer(std::string_view token, long long& value);
bool parse_real(std::string_view token, double& value);
/// Lower-case copy.
std::string lowercase(std::string_view text);

inline constexpr bool kHostIsLittleEndian = std::endian::native == std::endian::little;

}  // namespace incise::io_detail
