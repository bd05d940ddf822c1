#pragma once
// The cutter's collision tests on worker threads. Each candidate is tested on its own: the
// tests are pure functions of the mesh, the positions and the blade (they read, never write),
// and the results are gathered in the candidates' order, so a cut is the same tetrahedra, bit
// for bit, at any thread count. Internal to the cut module.

#include <cstddef>
#include <span>
#include <vector>

#include "incise/core/parallel_for.hpp"

namespace incise::cutter_detail {

/// Below this many candidates a loop stays on the calling thread: handing out the work costs
/// more than the few microseconds it saves.
inline constexpr std::size_t kParallelTests = 96;
/// Candidates per piece of work (each test takes about a microsecond).
inline constexpr std::size_t kTestGrain = 24;

/// results[i] = test(items[i]) for every i, on worker threads when there are enough items.
/// `Result` must not be bool (std::vector<bool> packs bits that two threads would share).
template <typename Item, typename Result, typename Test>
void test_each(std::span<const Item> items, std::vector<Result>& results, const Test& test) {
  results.resize(items.size());
  const auto body = [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      results[i] = test(items[i]);
    }
  };
  if (items.size() < kParallelTests) {
    body(0, items.size());
  } else {
    parallel_for(0, items.size(), kTestGrain, body);
  }
}

}  // namespace incise::cutter_detail
