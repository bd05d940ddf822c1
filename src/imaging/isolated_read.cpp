#include "isolated_read.hpp"

#include <fmt/format.h>

#include <csignal>
#include <cstring>
#include <exception>
#include <string>

#include "incise/core/child_process.hpp"
#include "incise/core/error.hpp"

namespace incise::imaging {
namespace {

// What the child sends: one tag byte, then the payload (host byte order: same machine).
constexpr char kVolume = 'V';
constexpr char kInputError = 'E';
constexpr char kOtherError = 'X';

void put_bytes(std::string& out, const void* data, std::size_t size) {
  out.append(static_cast<const char*>(data), size);
}
template <typename T>
void put(std::string& out, const T& value) {
  put_bytes(out, &value, sizeof(T));
}
void put_text(std::string& out, const std::string& text) {
  put<std::uint64_t>(out, text.size());
  out += text;
}

/// Reads what the child sent, bounds-checked (a child that died half-way sends less).
class Received {
 public:
  explicit Received(const std::string& bytes) : bytes_(bytes) {}
  [[nodiscard]] bool take(void* data, std::size_t size) {
    if (size > bytes_.size() - at_) {
      return false;
    }
    std::memcpy(data, bytes_.data() + at_, size);
    at_ += size;
    return true;
  }
  template <typename T>
  [[nodiscard]] bool take(T& value) {
    return take(&value, sizeof(T));
  }
  [[nodiscard]] bool take_text(std::string& text) {
    std::uint64_t size = 0;
    if (!take(size) || size > bytes_.size() - at_) {
      return false;
    }
    text.assign(bytes_.data() + at_, size);
    at_ += size;
    return true;
  }

 private:
  const std::string& bytes_;
  std::size_t at_ = 0;
};

void child(const std::function<VolumeImage()>& read, int fd) {
  std::string out;
  try {
    const VolumeImage image = read();
    out += kVolume;
    for (std::size_t n : image.size) {
      put<std::uint64_t>(out, n);
    }
    put_bytes(out, image.spacing.data(), 3 * sizeof(double));
    put_bytes(out, image.origin.data(), 3 * sizeof(double));
    put_bytes(out, image.direction.data(), 9 * sizeof(double));
    put_text(out, image.description);
    put<std::uint64_t>(out, image.values.size());
    put_bytes(out, image.values.data(), image.values.size() * sizeof(float));
  } catch (const InputError& error) {
    out.assign(1, kInputError);
    put_text(out, error.file());
    put<std::uint64_t>(out, error.line());
    put_text(out, error.what());
  } catch (const std::exception& error) {
    out.assign(1, kOtherError);
    put_text(out, error.what());
  } catch (...) {
    out.assign(1, kOtherError);
    put_text(out, "an unknown exception");
  }
  (void)write_all(fd, out.data(), out.size());
}

/// The message of an InputError's what() without the "file:line: " its constructor adds.
std::string message_of(const std::string& what, const std::string& file, std::size_t line) {
  std::string prefix = file;
  if (line > 0) {
    prefix += ":" + std::to_string(line);
  }
  prefix += ": ";
  return !file.empty() && what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what;
}

}  // namespace

VolumeImage read_in_child(const std::function<VolumeImage()>& read,
                          const std::filesystem::path& shown, const char* library,
                          double timeout_seconds) {
  const auto fail = [&](const std::string& why) -> InputError {
    return InputError(shown.string(), 0, fmt::format("{} {}; nothing was read", library, why));
  };
  const ChildOutcome outcome = run_in_child([&](int fd) { child(read, fd); }, timeout_seconds);
  if (!outcome.start_error.empty()) {
    throw fail("could not be started (" + outcome.start_error + ")");
  }
  if (outcome.timed_out) {
    throw fail(fmt::format("gave no answer within {:g} s", timeout_seconds));
  }
  if (outcome.signal != 0) {
    throw fail(
        fmt::format("stopped on this file ({}{}: the library's own check failed or it "
                    "crashed)",
                    outcome.signal == SIGABRT ? "an assertion, " : "", strsignal(outcome.signal)));
  }
  const std::string& received = outcome.output;
  Received in(received);
  char tag = 0;
  if (!in.take(tag)) {
    throw fail("ended without an answer");
  }
  if (tag == kInputError) {
    std::string file;
    std::uint64_t line = 0;
    std::string what;
    if (in.take_text(file) && in.take(line) && in.take_text(what)) {
      throw InputError(file, line, message_of(what, file, line));
    }
  } else if (tag == kOtherError) {
    std::string what;
    if (in.take_text(what)) {
      throw fail("failed: " + what);
    }
  } else if (tag == kVolume) {
    VolumeImage image;
    std::uint64_t count = 0;
    bool ok = true;
    for (std::size_t& n : image.size) {
      std::uint64_t value = 0;
      ok = ok && in.take(value);
      n = value;
    }
    ok = ok && in.take(image.spacing.data(), 3 * sizeof(double)) &&
         in.take(image.origin.data(), 3 * sizeof(double)) &&
         in.take(image.direction.data(), 9 * sizeof(double)) && in.take_text(image.description) &&
         in.take(count) && count <= received.size() / sizeof(float);
    if (ok) {
      image.values.resize(count);
      if (in.take(image.values.data(), count * sizeof(float))) {
        return image;
      }
    }
  }
  throw fail("sent an incomplete answer");
}

}  // namespace incise::imaging
