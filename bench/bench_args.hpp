#pragma once
// Command-line helpers shared by the benchmarks.

#include <cstdlib>
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

}  // namespace incise::bench
