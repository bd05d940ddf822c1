#pragma once
// Whether this machine's CPU runs AVX2 with FMA. The hand-written kernels (the block matrix's
// rows, the corotational batch, the coarse cycle's product) are compiled for it beside the
// portable build and chosen at run time by this.

namespace incise {

/// True on an x86-64 CPU with AVX2 and FMA (asked once, a property of the machine).
[[nodiscard]] inline bool cpu_has_avx2_fma() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  static const bool avx2 = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  }();
  return avx2;
#else
  return false;
#endif
}

}  // namespace incise
