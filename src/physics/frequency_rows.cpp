#include "incise/physics/frequency_rows.hpp"

#include <algorithm>

#include "incise/core/parallel_for.hpp"

namespace incise {

void FrequencyRows::fill(std::size_t rows, const std::function<double(VertexId)>& row) {
  rows_.assign(rows, 0.0);
  parallel_for(0, rows, 512, [&](std::size_t first, std::size_t last) {
    for (std::size_t v = first; v != last; ++v) {
      rows_[v] = row(static_cast<VertexId>(v));
    }
  });
  lost_largest_ = true;
  settle();
}

void FrequencyRows::set(VertexId vertex, double row) {
  double& kept = rows_[static_cast<std::size_t>(vertex)];
  lost_largest_ = lost_largest_ || (kept == largest_ && row < kept);
  kept = row;
  largest_ = std::max(largest_, row);
}

void FrequencyRows::settle() {
  if (lost_largest_) {
    largest_ = rows_.empty() ? 0.0 : *std::max_element(rows_.begin(), rows_.end());
    lost_largest_ = false;
  }
}

}  // namespace incise
