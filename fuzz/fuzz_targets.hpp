#pragma once
// Every input incise reads from outside, as a fuzz target: bytes in, and either a result or
// an InputError out. Anything else (another exception, a crash, a hang, an allocation sized
// by an untrusted count) is a finding. The same targets run under libFuzzer (fuzz_<name>,
// built with -DINCISE_FUZZ=ON and clang) and, in every build, under fuzz_replay, which CTest
// uses to replay the seed corpora and every past finding in fuzz/corpus/<name>.

#include <cstdint>
#include <span>
#include <string_view>

namespace incise::fuzz {

struct Target {
  const char* name;
  const char* extension;  ///< the file name an input is given (readers break ties by it)
  void (*run)(std::string_view bytes);
};

/// All targets, by name.
[[nodiscard]] std::span<const Target> targets();
[[nodiscard]] const Target* find_target(std::string_view name);

/// Runs one input through a target. InputError is the expected answer to bad input; any other
/// exception is printed and aborts the process (so that libFuzzer keeps the input).
void run_one(const Target& target, std::string_view bytes);

}  // namespace incise::fuzz
