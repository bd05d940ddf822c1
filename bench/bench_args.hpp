#pragma once
// Command-line helpers shared by the benchmarks.

#include <tbb/global_control.h>

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <vector>

namespace incise::bench {

/// "0.5,1,2" -> {0.5, 1, 2}.
inline std::vector<double> comma_separated(const char* text) {
  std::vector<double> values;
  for (const char* p = text; *p != '\0';) {
    values.push_back(std::atof(p));
    while (*p != '\0' && *p != ',') {
      ++p;
    }
    if (*p == ',') {
      ++p;
    }
  }
  return values;
}

/// "10,20,40" -> {10, 20, 40}.
inline std::vector<int> comma_separated_ints(const char* text) {
  std::vector<int> values;
  for (double value : comma_separated(text)) {
    values.push_back(static_cast<int>(value));
  }
  return values;
}

/// --threads N: holds TBB to N workers (at least 1) while the result lives.
inline std::unique_ptr<tbb::global_control> thread_limit(const char* text) {
  return std::make_unique<tbb::global_control>(
      tbb::global_control::max_allowed_parallelism,
      static_cast<std::size_t>(std::max(1, std::atoi(text))));
}

}  // namespace incise::bench
