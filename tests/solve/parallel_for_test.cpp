// The one parallel loop (include/incise/core/parallel_for.hpp): every index visited once,
// nothing outside the range touched, and a body's exception reaches the caller. The
// ThreadSanitizer build runs these on its plain threads.

#include "incise/core/parallel_for.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

namespace incise {
namespace {

TEST(Parallel, EveryIndexOnceAndNothingElse) {
  for (const std::size_t n : {0UL, 1UL, 7UL, 1000UL, 100003UL}) {
    for (const std::size_t grain : {0UL, 1UL, 64UL, 4096UL}) {
      std::vector<std::atomic<int>> visits(n);
      parallel_for(0, n, grain, [&](std::size_t first, std::size_t last) {
        ASSERT_LT(first, last);
        for (std::size_t i = first; i < last; ++i) {
          ++visits[i];
        }
      });
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_EQ(visits[i].load(), 1) << "index " << i << " of " << n << ", grain " << grain;
      }
    }
  }
  // An offset range: nothing before `begin` is touched.
  std::vector<int> values(100, 0);
  parallel_for(40, 100, 8, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i < last; ++i) {
      values[i] = 1;
    }
  });
  for (std::size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(values[i], i >= 40 ? 1 : 0) << i;
  }
}

TEST(Parallel, AnExceptionInABodyReachesTheCaller) {
  EXPECT_THROW(parallel_for(0, 10000, 16,
                            [](std::size_t first, std::size_t last) {
                              if (first <= 5000 && 5000 < last) {
                                throw std::runtime_error("element 5000");
                              }
                            }),
               std::runtime_error);
}

}  // namespace
}  // namespace incise
