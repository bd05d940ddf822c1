#pragma once
// The coarse cycle's 6x6 blocks stored as 8-bit integers times one scale per block, for the
// product that each of CG's iterations reads: 56 bytes a block where single precision took
// 144. The cycle is a preconditioner, and its precision is not what limits it: on the 384k-tet
// box CG needs 75 iterations from a cold start with these blocks in single precision, in 15
// bits or in 8 (127 levels), 81 with 4 bits and 205 with 2 (BENCHMARKS.md, session 57), while
// at 384k the product is bound by memory (about 10 MB a pass in single precision). The cycle
// stays symmetric: a block and its mirror round to the exact transpose of each other (the
// same entries and the same scale).

#include <array>
#include <cstddef>
#include <cstdint>

#include "rigid_block_maths.hpp"

namespace incise::coarse {

/// A 6x6 block as scale * q: q in [-127, 127], column by column, each column padded to 8.
struct QuantizedModeMatrix {
  std::array<std::int8_t, 48> columns{};
  double scale = 0.0;
};

/// The block rounded to 8 bits: scale = max |entry| / 127, each entry to the nearest level.
[[nodiscard]] QuantizedModeMatrix quantize(const ModeMatrix& block);
/// The block it stands for, scale * q.
[[nodiscard]] ModeMatrix dequantize(const QuantizedModeMatrix& block);

/// residual - sum over k in [first, last) of blocks[k] y[columns[k]], the products summed first
/// in slot order (in double), then subtracted.
[[nodiscard]] Modes subtract_quantized_products(const QuantizedModeMatrix* blocks,
                                                const int* columns, std::size_t first,
                                                std::size_t last, const Modes* y,
                                                const Modes& residual);

}  // namespace incise::coarse
