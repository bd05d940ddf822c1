#include "isolated_read.hpp"

#include <fmt/format.h>

#include <csignal>
#include <cstdint>
#include <cstring>
#include <exception>
#include <new>
#include <string>

#include "incise/core/child_process.hpp"
#include "incise/core/error.hpp"
#include "incise/core/state_archive.hpp"

namespace incise::imaging {
namespace {

// What the child sends: one tag byte, then the payload, written with the checkpoints'
// StateWriter and read back bounds-checked (a child that died half-way sends less).
constexpr char kVolume = 'V';
constexpr char kInputError = 'E';
constexpr char kOtherError = 'X';

void child(const std::function<VolumeImage()>& read, int fd, const std::filesystem::path& shown,
           const char* library, std::size_t memory_budget) {
  StateWriter out;
  try {
    const VolumeImage image = read();
    out.value(kVolume);
    out.value(image.size);
    out.value(image.spacing);
    out.value(image.origin);
    out.value(image.direction);
    out.text(image.description);
    out.values(image.values);
  } catch (const InputError& error) {
    out = StateWriter();
    out.value(kInputError);
    out.text(error.file());
    out.value<std::uint64_t>(error.line());
    out.text(error.what());
  } catch (const std::bad_alloc&) {
    out = StateWriter();
    out.value(kInputError);
    out.text(shown.string());
    out.value<std::uint64_t>(0);
    out.text(memory_budget > 0 && child_memory_budget_applies()
                 ? fmt::format("{} asked for more memory than a volume of this size can need "
                               "(over {} MB; the file claims more data than it holds); nothing "
                               "was read",
                               library, memory_budget >> 20)
                 : std::string("not enough memory to read the volume; nothing was read"));
  } catch (const std::exception& error) {
    out = StateWriter();
    out.value(kOtherError);
    out.text(error.what());
  } catch (...) {
    out = StateWriter();
    out.value(kOtherError);
    out.text("an unknown exception");
  }
  (void)write_all(fd, out.bytes().data(), out.bytes().size());
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
                          double timeout_seconds, std::size_t memory_budget) {
  const auto fail = [&](const std::string& why) -> InputError {
    return InputError(shown.string(), 0, fmt::format("{} {}; nothing was read", library, why));
  };
  const ChildOutcome outcome =
      run_in_child([&](int fd) { child(read, fd, shown, library, memory_budget); }, timeout_seconds,
                   memory_budget);
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
  StateReader in(outcome.output, shown.string());
  char tag = 0;
  try {
    tag = in.value<char>("tag");
    if (tag == kVolume) {
      VolumeImage image;
      image.size = in.value<std::array<std::size_t, 3>>("size");
      image.spacing = in.value<Vec3>("spacing");
      image.origin = in.value<Vec3>("origin");
      image.direction = in.value<Eigen::Matrix3d>("direction");
      image.description = in.text("description");
      image.values = in.values<float>("values");
      return image;
    }
  } catch (const InputError&) {
    throw fail(outcome.output.empty() ? "ended without an answer" : "sent an incomplete answer");
  }
  if (tag != kInputError && tag != kOtherError) {
    throw fail("sent an unreadable answer");
  }
  std::string file;
  std::uint64_t line = 0;
  std::string what;
  try {
    if (tag == kInputError) {
      file = in.text("file");
      line = in.value<std::uint64_t>("line");
    }
    what = in.text("message");
  } catch (const InputError&) {
    throw fail("sent an incomplete answer");
  }
  if (tag == kOtherError) {
    throw fail("failed: " + what);
  }
  throw InputError(file, line, message_of(what, file, line));
}

}  // namespace incise::imaging
