// std::cout silenced from several threads at once, each writing through it meanwhile (the
// planning meshers run side by side and both print): nothing reaches the caller's buffer, no
// write corrupts anything, and the caller's buffer is back once the last silencer is gone.

#include "incise/core/silenced_standard_output.hpp"

#include <gtest/gtest.h>

#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace incise {
namespace {

TEST(SilencedStandardOutput, ThreadsHoldingItAtOnceWriteNowhereAndTheCallersBufferComesBack) {
  std::ostringstream caller;
  std::streambuf* const before = std::cout.rdbuf(caller.rdbuf());
  const std::string line(200, 'x');  // longer than a small buffer: growing one reallocates
  {
    const SilencedStandardOutput outer;  // held across the threads' silencers, as nested
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&line] {
        for (int round = 0; round < 200; ++round) {
          const SilencedStandardOutput quiet;  // overlapping the other threads' ones
          for (int k = 0; k < 50; ++k) {
            std::cout << line << k << '\n';
          }
        }
      });
    }
    for (std::thread& thread : threads) {
      thread.join();
    }
    std::cout << "still silenced";
  }
  std::cout << "heard";
  std::cout.flush();
  EXPECT_EQ(std::cout.rdbuf(), caller.rdbuf());
  std::cout.rdbuf(before);
  EXPECT_EQ(caller.str(), "heard");
}

}  // namespace
}  // namespace incise
