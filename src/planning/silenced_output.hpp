#pragma once
// std::cout sent nowhere for a scope (private to planning).

#include <iostream>
#include <sstream>

namespace incise::planning {

/// While alive, what is written to std::cout goes nowhere. CGAL's image seeding prints its
/// progress there, and std::cout belongs to the caller (a script may read incise's standard
/// output). Swapping the buffer is not thread-safe: hold one around meshers run side by side,
/// not one per mesher.
class SilencedStandardOutput {
 public:
  SilencedStandardOutput() : standard_output_(std::cout.rdbuf(discarded_.rdbuf())) {}
  ~SilencedStandardOutput() { std::cout.rdbuf(standard_output_); }
  SilencedStandardOutput(const SilencedStandardOutput&) = delete;
  SilencedStandardOutput& operator=(const SilencedStandardOutput&) = delete;

 private:
  std::ostringstream discarded_;
  std::streambuf* standard_output_;
};

}  // namespace incise::planning
