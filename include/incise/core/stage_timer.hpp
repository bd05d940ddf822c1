#pragma once
// Wall-clock timing of named pipeline stages (the seed's Table 1: cd, gc, rx, rd).

#include <chrono>
#include <map>
#include <string>

namespace incise {

/// Accumulates wall-clock time (s) per named stage.
class StageTimer {
 public:
  using Clock = std::chrono::steady_clock;

  /// Adds `seconds` to `stage`.
  void add(const std::string& stage, double seconds) { totals_[stage] += seconds; }
  [[nodiscard]] double total(const std::string& stage) const;
  [[nodiscard]] const std::map<std::string, double>& totals() const { return totals_; }
  void clear() { totals_.clear(); }

  /// Times a scope and adds it to the stage on destruction.
  class Scope {
   public:
    Scope(StageTimer& timer, std::string stage)
        : timer_(timer), stage_(std::move(stage)), start_(Clock::now()) {}
    ~Scope() { timer_.add(stage_, std::chrono::duration<double>(Clock::now() - start_).count()); }
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    StageTimer& timer_;
    std::string stage_;
    Clock::time_point start_;
  };

  [[nodiscard]] Scope scope(std::string stage) { return Scope(*this, std::move(stage)); }

 private:
  std::map<std::string, double> totals_;
};

}  // namespace incise
