#include "source.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

namespace incise::io_detail {

Source Source::open(const std::filesystem::path& path) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    throw InputError(path.string(), 0, "no such file (or not a regular file)");
  }
  std::ifstream stream(path, std::ios::binary);
  if (!stream) {
    throw InputError(path.string(), 0, "cannot open for reading");
  }
  std::ostringstream buffer;
  buffer << stream.rdbuf();
  if (stream.bad()) {
    throw InputError(path.string(), 0, "read error");
  }
  return Source(path.string(), std::move(buffer).str());
}

void Source::seek(std::size_t offset) {
  offset_ = std::min(offset, bytes_.size());
  line_ = 1 + static_cast<std::size_t>(std::count(
                  bytes_.begin(), bytes_.begin() + static_cast<std::ptrdiff_t>(offset_), '\n'));
}

void Source::skip_space_and_comments() {
  while (offset_ < bytes_.size()) {
    const char c = bytes_[offset_];
    if (c == '\n') {
      ++line_;
      ++offset_;
    } else if (std::isspace(static_cast<unsigned char>(c)) != 0) {
      ++offset_;
    } else if (comment_ != 0 && c == comment_) {
      while (offset_ < bytes_.size() && bytes_[offset_] != '\n') {
        ++offset_;
      }
    } else {
      return;
    }
  }
}

std::string_view Source::next_token() {
  skip_space_and_comments();
  const std::size_t start = offset_;
  while (offset_ < bytes_.size() &&
         std::isspace(static_cast<unsigned char>(bytes_[offset_])) == 0 &&
         !(comment_ != 0 && bytes_[offset_] == comment_)) {
    ++offset_;
  }
  return std::string_view(bytes_).substr(start, offset_ - start);
}

std::string_view Source::token(const char* what) {
  const std::string_view result = next_token();
  if (result.empty()) {
    // Name the last line with content, not the empty line after the final newline.
    const std::size_t last = bytes_.find_last_not_of(" \t\r\n");
    const auto line =
        last == std::string::npos
            ? 1
            : 1 + static_cast<std::size_t>(std::count(
                      bytes_.begin(), bytes_.begin() + static_cast<std::ptrdiff_t>(last), '\n'));
    throw InputError(name_, line_numbers_ ? line : 0,
                     std::string("unexpected end of file while reading ") + what);
  }
  return result;
}

std::string_view Source::peek_token() {
  const std::size_t saved_offset = offset_;
  const std::size_t saved_line = line_;
  const std::string_view result = next_token();
  offset_ = saved_offset;
  line_ = saved_line;
  return result;
}

bool Source::token_on_this_line() {
  while (offset_ < bytes_.size()) {
    const char c = bytes_[offset_];
    if (c == '\n') {
      return false;
    }
    if (comment_ != 0 && c == comment_) {
      return false;
    }
    if (std::isspace(static_cast<unsigned char>(c)) == 0) {
      return true;
    }
    ++offset_;
  }
  return false;
}

std::string_view Source::rest_of_line() {
  const std::size_t start = offset_;
  while (offset_ < bytes_.size() && bytes_[offset_] != '\n') {
    ++offset_;
  }
  std::string_view result = std::string_view(bytes_).substr(start, offset_ - start);
  if (offset_ < bytes_.size()) {
    ++offset_;
    ++line_;
  }
  if (!result.empty() && result.back() == '\r') {
    result.remove_suffix(1);
  }
  return result;
}

bool parse_integer(std::string_view token, long long& value) {
  if (!token.empty() && token.front() == '+') {
    token.remove_prefix(1);
  }
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  return error == std::errc() && end == token.data() + token.size() && !token.empty();
}

bool parse_real(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') {
    token.remove_prefix(1);
  }
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  return error == std::errc() && end == token.data() + token.size() && !token.empty();
}

std::string lowercase(std::string_view text) {
  std::string result(text);
  std::transform(result.begin(), result.end(), result.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return result;
}

long long Source::integer(const char* what) {
  const std::string_view text = token(what);
  long long value = 0;
  if (!parse_integer(text, value)) {
    fail(std::string("expected an integer for ") + what + ", found '" + std::string(text) + "'");
  }
  return value;
}

double Source::real(const char* what) {
  const std::string_view text = token(what);
  double value = 0.0;
  if (!parse_real(text, value)) {
    fail(std::string("expected a number for ") + what + ", found '" + std::string(text) + "'");
  }
  if (!std::isfinite(value)) {
    fail(std::string(what) + " is not finite ('" + std::string(text) + "')");
  }
  return value;
}

std::size_t Source::count(const char* what, std::size_t limit) {
  const long long value = integer(what);
  if (value < 0 || static_cast<unsigned long long>(value) > limit) {
    fail(std::string(what) + " " + std::to_string(value) + " is out of range");
  }
  return static_cast<std::size_t>(value);
}

void Source::expect(std::string_view keyword) {
  const std::string_view found = next_token();
  if (found != keyword) {
    fail("expected '" + std::string(keyword) + "', found '" +
         (found.empty() ? std::string("end of file") : std::string(found)) + "'");
  }
}

void Source::read_bytes(void* destination, std::size_t n, const char* what) {
  if (remaining() < n) {
    fail_without_line(std::string("file ends inside binary data (") + what + ")");
  }
  std::memcpy(destination, bytes_.data() + offset_, n);
  for (std::size_t i = offset_; i < offset_ + n; ++i) {
    line_ += bytes_[i] == '\n' ? 1 : 0;
  }
  offset_ += n;
}

void Source::require_room(std::size_t values, std::size_t bytes_per_value, const char* what) const {
  if (values == 0) {
    return;
  }
  const std::size_t left = remaining();
  // Counts come from a header (at most 2^31 by every reader), so the products cannot wrap.
  const bool fits =
      bytes_per_value == 0 ? text_can_hold(values, left) : values * bytes_per_value <= left;
  if (!fits) {
    fail(std::string(what) + ": " + std::to_string(values) + " values declared, but only " +
         std::to_string(left) + " bytes are left in the file");
  }
}

void Source::fail(const std::string& message) const {
  throw InputError(name_, line_numbers_ ? line_ : 0, message);
}

void Source::fail_without_line(const std::string& message) const {
  throw InputError(name_, 0, message + " at byte " + std::to_string(offset_));
}

}  // namespace incise::io_detail
