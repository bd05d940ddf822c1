#include "incise/core/stage_timer.hpp"

namespace incise {

double StageTimer::total(const std::string& stage) const {
  const auto it = totals_.find(stage);
  return it == totals_.end() ? 0.0 : it->second;
}

}  // namespace incise
