// Cell numbers of coordinates anywhere (core/clamped_floor.hpp): floor inside the range, the
// range's ends beyond it, the low end for NaN, never a conversion a long cannot hold.

#include "incise/core/clamped_floor.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace incise {
namespace {

TEST(ClampedFloor, FloorsInsideTheRangeAndSaturatesOutside) {
  EXPECT_EQ(clamped_floor(2.7, 0, 9), 2);
  EXPECT_EQ(clamped_floor(-2.3, -5, 5), -3);
  EXPECT_EQ(clamped_floor(3.0, -5, 5), 3);
  EXPECT_EQ(clamped_floor(-0.5, 0, 9), 0);
  EXPECT_EQ(clamped_floor(9.5, 0, 9), 9);
  EXPECT_EQ(clamped_floor(12.0, 0, 9), 9);
  constexpr long kFar = 1L << 40;
  EXPECT_EQ(clamped_floor(1e300, -kFar, kFar), kFar);
  EXPECT_EQ(clamped_floor(-1e300, -kFar, kFar), -kFar);
  EXPECT_EQ(clamped_floor(std::numeric_limits<double>::infinity(), -kFar, kFar), kFar);
  EXPECT_EQ(clamped_floor(-std::numeric_limits<double>::infinity(), -kFar, kFar), -kFar);
  EXPECT_EQ(clamped_floor(std::numeric_limits<double>::quiet_NaN(), -kFar, kFar), -kFar);
}

}  // namespace
}  // namespace incise
