#pragma once
// std::cout sent nowhere for a scope. CGAL's image seeding prints its progress there, and
// std::cout belongs to the caller (a script may read incise's standard output).

namespace incise {

/// While any one is alive, what is written to std::cout goes nowhere. Safe to hold from several
/// threads at once, nested or overlapping, with those threads writing to std::cout meanwhile:
/// the first one in swaps std::cout's buffer for one that keeps no state, the last one out puts
/// the caller's back. (The planning meshers run side by side and both print; one shared string
/// buffer there corrupted the heap now and then: "munmap_chunk(): invalid pointer".) Another
/// thread's own output to std::cout is discarded too while one is held.
class SilencedStandardOutput {
 public:
  SilencedStandardOutput();
  ~SilencedStandardOutput();
  SilencedStandardOutput(const SilencedStandardOutput&) = delete;
  SilencedStandardOutput& operator=(const SilencedStandardOutput&) = delete;
};

}  // namespace incise
