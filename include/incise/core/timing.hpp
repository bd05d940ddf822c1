#pragma once
// Wall-clock timing of stages (s), for the per-stage reports and benchmarks.

#include <chrono>

namespace incise {

using Clock = std::chrono::steady_clock;

/// Seconds elapsed since `start`.
[[nodiscard]] inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace incise
