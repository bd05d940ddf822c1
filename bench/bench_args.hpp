#pragma once
// Command-line helpers shared by the benchmarks.

#include <cstdlib>
#include <vector>

namespace incise::bench {

/// "10,20,40" -> {10, 20, 40}.
inline std::vector<int> comma_separated_ints(const char* text) {
  std::vector<int> values;
  for (const char* p = text; *p != '\0';) {
    values.push_back(std::atoi(p));
    while (*p != '\0' && *p != ',') {
      ++p;
    }
    if (*p == ',') {
      ++p;
    }
  }
  return values;
}

}  // namespace incise::bench
