#pragma once
// Reading JSON input files (scenes, plans) with messages that name the file, the line and the
// key: `Context` knows the file and its text, `ObjectReader` reads one object and refuses keys
// it does not know (suggesting the nearest valid one). Header-only; users link nlohmann_json.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/core/types.hpp"

namespace incise::json {

using Json = nlohmann::json;

inline std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) {
    row[j] = j;
  }
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

inline std::string type_name(const Json& value) {
  if (value.is_number()) {
    return "a number";
  }
  if (value.is_string()) {
    return "a string";
  }
  if (value.is_boolean()) {
    return "true/false";
  }
  if (value.is_array()) {
    return "a list";
  }
  if (value.is_object()) {
    return "an object";
  }
  return "null";
}

/// Error context: the file, its text (to find the line of a key) and where in the scene we are.
class Context {
 public:
  /// `what` names the kind of file in messages ("scene", "plan").
  Context(std::string text, std::filesystem::path file, std::string what = "scene")
      : text_(std::move(text)), file_(std::move(file)), what_(std::move(what)) {}

  /// Throws an InputError naming the file, the line of `path` (a dotted key) and the key.
  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw InputError(name(), line_of(path), what_ + " key '" + path + "': " + message);
  }
  /// Throws an InputError naming the file and a line.
  [[noreturn]] void fail_line(std::size_t line, const std::string& message) const {
    throw InputError(name(), line, message);
  }
  /// The file's name in messages ("<default scene>" when there is none).
  [[nodiscard]] std::string name() const {
    return file_.empty() ? "<default " + what_ + ">" : file_.string();
  }
  /// The file (empty for built-in text).
  [[nodiscard]] const std::filesystem::path& file() const { return file_; }

  /// The text parsed as JSON. Any failure of the parser (bad syntax, and also a number too
  /// large for a double, which nlohmann reports as out_of_range) is an InputError naming the
  /// file and, where it can be found, the line.
  [[nodiscard]] Json parse() const {
    try {
      return Json::parse(text_);
    } catch (const Json::parse_error& error) {
      const auto byte = std::min<std::size_t>(error.byte, text_.size());
      fail_line(line_at(byte > 0 ? byte - 1 : 0), "malformed JSON: " + reason(error));
    } catch (const Json::exception& error) {
      // No byte offset: find the quoted token the message names ("... parsing '1E999'").
      const std::string message = error.what();
      const std::size_t open = message.find('\'');
      const std::size_t close = message.rfind('\'');
      std::size_t line = 0;
      if (open != std::string::npos && close > open + 1) {
        const std::size_t at = text_.find(message.substr(open + 1, close - open - 1));
        line = at == std::string::npos ? 0 : line_at(at);
      }
      fail_line(line, "malformed JSON: " + reason(error));
    }
  }

  /// Line of the first occurrence of the last key of `path` in the text (best effort).
  [[nodiscard]] std::size_t line_of(const std::string& path) const {
    std::string key = path.substr(path.find_last_of('.') + 1);
    key = key.substr(0, key.find('['));
    const std::size_t at = text_.find("\"" + key + "\"");
    if (at == std::string::npos) {
      return 0;
    }
    return line_at(at);
  }

 private:
  [[nodiscard]] std::size_t line_at(std::size_t byte) const {
    byte = std::min(byte, text_.size());
    return 1 + static_cast<std::size_t>(std::count(
                   text_.begin(), text_.begin() + static_cast<std::ptrdiff_t>(byte), '\n'));
  }
  /// nlohmann's message without its "[json.exception...] " prefix.
  static std::string reason(const Json::exception& error) {
    std::string what = error.what();
    const std::size_t end = what.find("] ");
    return end == std::string::npos ? what : what.substr(end + 2);
  }

  std::string text_;
  std::filesystem::path file_;
  std::string what_;
};

/// Reads one JSON object, refusing keys it does not know.
class ObjectReader {
 public:
  /// Reads `object` found at `path` (dotted, "" at the top); a key not in `allowed` fails
  /// with the closest allowed one suggested.
  ObjectReader(const Context& context, const Json& object, std::string path,
               std::vector<std::string> allowed)
      : context_(context), object_(object), path_(std::move(path)), allowed_(std::move(allowed)) {
    if (!object_.is_object()) {
      context_.fail(path_.empty() ? "(top level)" : path_,
                    "must be an object, not " + type_name(object_));
    }
    for (const auto& [key, value] : object_.items()) {
      if (std::find(allowed_.begin(), allowed_.end(), key) == allowed_.end()) {
        std::string closest;
        std::size_t best = std::string::npos;
        for (const std::string& candidate : allowed_) {
          const std::size_t distance = edit_distance(key, candidate);
          if (distance < best) {
            best = distance;
            closest = candidate;
          }
        }
        std::string valid;
        for (const std::string& candidate : allowed_) {
          valid += (valid.empty() ? "" : ", ") + candidate;
        }
        context_.fail(child(key),
                      "unknown key" +
                          (closest.empty() ? std::string() : "; did you mean '" + closest + "'?") +
                          " (valid here: " + valid + ")");
      }
    }
  }

  /// Whether the object has `key`.
  [[nodiscard]] bool has(const std::string& key) const { return object_.contains(key); }
  /// The value of `key`, which must be there.
  [[nodiscard]] const Json& at(const std::string& key) const { return object_.at(key); }
  /// The dotted path of `key` in this object, for messages.
  [[nodiscard]] std::string child(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }

  /// A finite number, or `fallback` when the key is absent.
  double number(const std::string& key, double fallback) const {
    if (!has(key)) {
      return fallback;
    }
    const Json& value = at(key);
    if (!value.is_number()) {
      context_.fail(child(key), "must be a number, not " + type_name(value));
    }
    const double result = value.get<double>();
    if (!std::isfinite(result)) {
      context_.fail(child(key), "must be finite");
    }
    return result;
  }
  /// The same, and > 0.
  double positive(const std::string& key, double fallback) const {
    const double value = number(key, fallback);
    if (!(value > 0.0)) {
      context_.fail(child(key), "must be positive");
    }
    return value;
  }
  /// The same, and >= 0.
  double non_negative(const std::string& key, double fallback) const {
    const double value = number(key, fallback);
    if (!(value >= 0.0)) {
      context_.fail(child(key), "must not be negative");
    }
    return value;
  }
  /// An integer in [low, high], or `fallback` when the key is absent.
  int integer(const std::string& key, int fallback, int low, int high) const {
    if (!has(key)) {
      return fallback;
    }
    const Json& value = at(key);
    if (!value.is_number_integer()) {
      context_.fail(child(key), "must be an integer, not " + type_name(value));
    }
    const long long result = value.get<long long>();
    if (result < low || result > high) {
      context_.fail(child(key),
                    "must lie in [" + std::to_string(low) + ", " + std::to_string(high) + "]");
    }
    return static_cast<int>(result);
  }
  /// true or false, or `fallback` when the key is absent.
  bool boolean(const std::string& key, bool fallback) const {
    if (!has(key)) {
      return fallback;
    }
    const Json& value = at(key);
    if (!value.is_boolean()) {
      context_.fail(child(key), "must be true or false, not " + type_name(value));
    }
    return value.get<bool>();
  }
  /// A string, or `fallback` when the key is absent.
  std::string string(const std::string& key, const std::string& fallback) const {
    if (!has(key)) {
      return fallback;
    }
    const Json& value = at(key);
    if (!value.is_string()) {
      context_.fail(child(key), "must be a string, not " + type_name(value));
    }
    return value.get<std::string>();
  }
  /// One of the names in `table` (name, value); an unknown name is an error listing them.
  template <typename Kind>
  Kind choice(const std::string& key, Kind fallback,
              std::span<const std::pair<std::string_view, Kind>> table,
              const std::string& what) const {
    if (!has(key)) {
      return fallback;
    }
    const std::string name = string(key, "");
    std::string known;
    for (const auto& [candidate, kind] : table) {
      if (candidate == name) {
        return kind;
      }
      known += (known.empty() ? "" : ", ") + std::string(candidate);
    }
    context_.fail(child(key), "unknown " + what + " '" + name + "' (known: " + known + ")");
  }
  /// Three finite numbers [x, y, z], or `fallback` when the key is absent.
  Vec3 vec3(const std::string& key, const Vec3& fallback) const {
    return has(key) ? parse_vec3(context_, at(key), child(key)) : fallback;
  }

  /// `value` as three finite numbers; fails naming `path` otherwise.
  static Vec3 parse_vec3(const Context& context, const Json& value, const std::string& path) {
    if (!value.is_array() || value.size() != 3 ||
        !std::all_of(value.begin(), value.end(), [](const Json& c) { return c.is_number(); })) {
      context.fail(path, "must be a list of three numbers [x, y, z]");
    }
    const Vec3 result(value[0].get<double>(), value[1].get<double>(), value[2].get<double>());
    if (!result.allFinite()) {
      context.fail(path, "must be finite");
    }
    return result;
  }

 private:
  const Context& context_;
  const Json& object_;
  std::string path_;
  std::vector<std::string> allowed_;
};

inline std::filesystem::path resolve(const Context& context, const std::string& path) {
  std::filesystem::path result(path);
  if (result.is_relative() && !context.file().empty()) {
    result = context.file().parent_path() / result;
  }
  return result.lexically_normal();
}

}  // namespace incise::json
