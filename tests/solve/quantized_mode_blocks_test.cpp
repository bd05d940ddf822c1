// The coarse cycle's 8-bit blocks: a block and its mirror must stay exact transposes (else the
// cycle, and so CG's preconditioner, is not symmetric), each entry within half a level of the
// block it stands for, and the hand-written product must be the product of those blocks.
#include "../../src/solve/quantized_mode_blocks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace incise::coarse {
namespace {

ModeMatrix random_block(std::mt19937& random) {
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  ModeMatrix block;
  for (int j = 0; j < kModes; ++j) {
    for (int i = 0; i < kModes; ++i) {
      // Entries over six orders of magnitude, as a block coupling translations and rotations.
      block(i, j) = entry(random) * std::pow(10.0, 3 - j);
    }
  }
  return block;
}

TEST(QuantizedModeBlocks, ABlockAndItsTransposeRoundToExactTransposesWithinHalfALevel) {
  std::mt19937 random(3);
  for (int trial = 0; trial < 50; ++trial) {
    const ModeMatrix block = random_block(random);
    const QuantizedModeMatrix quantized = quantize(block);
    const QuantizedModeMatrix mirror = quantize(block.transpose());
    EXPECT_EQ(quantized.scale, mirror.scale);
    EXPECT_EQ(dequantize(quantized), dequantize(mirror).transpose());
    EXPECT_DOUBLE_EQ(quantized.scale, block.cwiseAbs().maxCoeff() / 127.0);
    const ModeMatrix error = dequantize(quantized) - block;
    EXPECT_LE(error.cwiseAbs().maxCoeff(), 0.5 * quantized.scale * (1.0 + 1e-12));
  }
  EXPECT_EQ(dequantize(quantize(ModeMatrix::Zero())), ModeMatrix::Zero());
}

TEST(QuantizedModeBlocks, TheProductIsTheProductOfTheBlocksTheyStandFor) {
  std::mt19937 random(4);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  std::vector<QuantizedModeMatrix> blocks;
  std::vector<int> columns;
  std::vector<Modes> y(9);
  for (Modes& motion : y) {
    motion = Modes::NullaryExpr([&](Eigen::Index) { return entry(random); });
  }
  for (int k = 0; k < 7; ++k) {
    blocks.push_back(quantize(random_block(random)));
    columns.push_back((5 * k + 2) % 9);
  }
  const Modes c = Modes::NullaryExpr([&](Eigen::Index) { return entry(random); });
  // Slots 1 .. 6 (not from the first: a row's slots start anywhere in the level's arrays).
  Modes wanted = c;
  double size = c.cwiseAbs().maxCoeff();
  for (std::size_t k = 1; k < 7; ++k) {
    const Modes product = dequantize(blocks[k]) * y[static_cast<std::size_t>(columns[k])];
    wanted -= product;
    size += product.cwiseAbs().maxCoeff();
  }
  const Modes got = subtract_quantized_products(blocks.data(), columns.data(), 1, 7, y.data(), c);
  EXPECT_LE((got - wanted).cwiseAbs().maxCoeff(), 1e-13 * size) << got.transpose() << "\n"
                                                                << wanted.transpose();
}

}  // namespace
}  // namespace incise::coarse
