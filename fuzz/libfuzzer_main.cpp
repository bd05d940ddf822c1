// libFuzzer's entry for one target, named at compile time (INCISE_FUZZ_TARGET).

#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "fuzz_targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const incise::fuzz::Target* target = [] {
    const auto* found = incise::fuzz::find_target(INCISE_FUZZ_TARGET);
    if (found == nullptr) {
      std::abort();
    }
    return found;
  }();
  incise::fuzz::run_one(*target, std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}
