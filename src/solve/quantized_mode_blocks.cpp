#include "quantized_mode_blocks.hpp"

#include <algorithm>
#include <cmath>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define INCISE_HAVE_AVX2_QUANTIZED 1
#endif

#include "incise/core/cpu_features.hpp"

namespace incise::coarse {

namespace {

constexpr double kLevels = 127.0;
constexpr int kColumnStride = 8;

Modes quantized_products_portable(const QuantizedModeMatrix* blocks, const int* columns,
                                  std::size_t first, std::size_t last, const Modes* y) {
  Modes sum = Modes::Zero();
  for (std::size_t k = first; k != last; ++k) {
    const QuantizedModeMatrix& block = blocks[k];
    const Modes& motion = y[static_cast<std::size_t>(columns[k])];
    for (int j = 0; j < kModes; ++j) {
      const double factor = block.scale * motion(j);
      for (int i = 0; i < kModes; ++i) {
        sum(i) +=
            static_cast<double>(block.columns[static_cast<std::size_t>(kColumnStride * j + i)]) *
            factor;
      }
    }
  }
  return sum;
}

#ifdef INCISE_HAVE_AVX2_QUANTIZED
// By hand because the portable build (SSE2) has no 8-bit to double widening in few
// instructions: each column's eight bytes widen to rows 0-3 and 4-5 and add scale * y_j times
// them, in double.
__attribute__((target("avx2,fma"))) Modes quantized_products_avx2(const QuantizedModeMatrix* blocks,
                                                                  const int* columns,
                                                                  std::size_t first,
                                                                  std::size_t last,
                                                                  const Modes* y) {
  __m256d top = _mm256_setzero_pd();
  __m128d bottom = _mm_setzero_pd();
  for (std::size_t k = first; k != last; ++k) {
    const QuantizedModeMatrix& block = blocks[k];
    const double* motion = y[static_cast<std::size_t>(columns[k])].data();
    for (int j = 0; j < kModes; ++j) {
      const __m128i bytes = _mm_loadl_epi64(
          reinterpret_cast<const __m128i*>(block.columns.data() + kColumnStride * j));
      const __m128i words = _mm_cvtepi8_epi32(bytes);
      const __m128i lower = _mm_cvtepi8_epi32(_mm_srli_si128(bytes, 4));
      const double factor = block.scale * motion[j];
      top = _mm256_fmadd_pd(_mm256_cvtepi32_pd(words), _mm256_set1_pd(factor), top);
      bottom = _mm_fmadd_pd(_mm_cvtepi32_pd(lower), _mm_set1_pd(factor), bottom);
    }
  }
  alignas(32) double out[6];
  _mm256_store_pd(out, top);
  _mm_store_pd(out + 4, bottom);
  Modes sum;
  for (int i = 0; i < kModes; ++i) {
    sum(i) = out[i];
  }
  return sum;
}
#endif

}  // namespace

QuantizedModeMatrix quantize(const ModeMatrix& block) {
  QuantizedModeMatrix out;
  const double largest = block.cwiseAbs().maxCoeff();
  if (!(largest > 0.0) || !std::isfinite(largest)) {
    return out;  // zero (a non-finite block is caught where the matrix is factorised)
  }
  out.scale = largest / kLevels;
  for (int j = 0; j < kModes; ++j) {
    for (int i = 0; i < kModes; ++i) {
      const double level = std::clamp(std::nearbyint(block(i, j) / out.scale), -kLevels, kLevels);
      out.columns[static_cast<std::size_t>(kColumnStride * j + i)] =
          static_cast<std::int8_t>(level);
    }
  }
  return out;
}

ModeMatrix dequantize(const QuantizedModeMatrix& block) {
  ModeMatrix out;
  for (int j = 0; j < kModes; ++j) {
    for (int i = 0; i < kModes; ++i) {
      out(i, j) = block.scale * static_cast<double>(
                                    block.columns[static_cast<std::size_t>(kColumnStride * j + i)]);
    }
  }
  return out;
}

Modes subtract_quantized_products(const QuantizedModeMatrix* blocks, const int* columns,
                                  std::size_t first, std::size_t last, const Modes* y,
                                  const Modes& residual) {
#ifdef INCISE_HAVE_AVX2_QUANTIZED
  if (cpu_has_avx2_fma()) {
    return residual - quantized_products_avx2(blocks, columns, first, last, y);
  }
#endif
  return residual - quantized_products_portable(blocks, columns, first, last, y);
}

}  // namespace incise::coarse
