#pragma once
// The cell number of a coordinate in a grid, safe for any double: grids look up points that
// may lie anywhere (a blade pose far off in a path, a diverging body, a corrupt file), and a
// double beyond a long's range converts to long with undefined behaviour.

#include <cmath>

namespace incise {

/// floor(x) as a long, clamped to [low, high] before the conversion; NaN gives low.
[[nodiscard]] inline long clamped_floor(double x, long low, long high) {
  const double number = std::floor(x);
  if (!(number > static_cast<double>(low))) {
    return low;
  }
  return number < static_cast<double>(high) ? static_cast<long>(number) : high;
}

}  // namespace incise
