#include "incise/core/silenced_standard_output.hpp"

#include <iostream>
#include <mutex>
#include <streambuf>

namespace incise {

namespace {

/// Accepts and drops every character, with no buffer of its own: writes from any number of
/// threads at once touch no shared state (a string buffer grows and frees its storage).
class DiscardingBuffer final : public std::streambuf {
 protected:
  int_type overflow(int_type c) override { return traits_type::not_eof(c); }
  std::streamsize xsputn(const char* /*characters*/, std::streamsize count) override {
    return count;
  }
};

/// std::cout is one per process, so its silencing is too: how many silencers are alive, and
/// the buffer to put back after the last.
struct Silencing {
  std::mutex mutex;
  int holders = 0;
  std::streambuf* saved = nullptr;
  DiscardingBuffer discard;
};

Silencing& silencing() {
  static Silencing state;  // a process-wide resource (std::cout) needs process-wide bookkeeping
  return state;
}

}  // namespace

SilencedStandardOutput::SilencedStandardOutput() {
  Silencing& state = silencing();
  const std::lock_guard lock(state.mutex);
  if (state.holders++ == 0) {
    state.saved = std::cout.rdbuf(&state.discard);
  }
}

SilencedStandardOutput::~SilencedStandardOutput() {
  Silencing& state = silencing();
  const std::lock_guard lock(state.mutex);
  if (--state.holders == 0) {
    std::cout.rdbuf(state.saved);
    state.saved = nullptr;
  }
}

}  // namespace incise
