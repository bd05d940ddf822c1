#include "incise/physics/block_sparse.hpp"

#include <algorithm>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "incise/core/error.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/mesh/vertex_graph.hpp"

namespace incise {
namespace {

/// Copies `from` into `to`, growing `to` with slack so small growth does not reallocate.
template <typename T>
void copy_growing(const std::vector<T>& from, std::vector<T>& to) {
  if (to.capacity() < from.size()) {
    to.reserve(from.size() + from.size() / 4);
  }
  to.assign(from.begin(), from.end());
}

}  // namespace

void BlockSparseMatrix::build_pattern(const TetMesh& mesh) {
  build_pattern(vertex_graph(mesh), mesh.revision());
}

void BlockSparseMatrix::build_pattern(const VertexGraph& graph, std::uint64_t revision) {
  const std::size_t n = graph.row_start.size() - 1;
  // Each row: the diagonal, then the neighbours.
  row_start_.resize(n + 1);
  for (std::size_t v = 0; v <= n; ++v) {
    row_start_[v] = graph.row_start[v] + v;
  }
  columns_.resize(row_start_[n]);
  for (std::size_t v = 0; v < n; ++v) {
    columns_[row_start_[v]] = static_cast<VertexId>(v);
    const auto neighbours = graph.neighbors(static_cast<VertexId>(v));
    std::copy(neighbours.begin(), neighbours.end(),
              columns_.begin() + static_cast<std::ptrdiff_t>(row_start_[v] + 1));
  }
  diagonal_.resize(n);
  for (std::size_t v = 0; v < n; ++v) {
    // Sorted columns make products walk p in order and let find() bisect.
    std::sort(columns_.begin() + static_cast<std::ptrdiff_t>(row_start_[v]),
              columns_.begin() + static_cast<std::ptrdiff_t>(row_start_[v + 1]));
    diagonal_[v] = find(static_cast<VertexId>(v), static_cast<VertexId>(v));
  }
  zero_values();
  pattern_revision_ = revision;
}

void BlockSparseMatrix::match_pattern(const BlockSparseMatrix& other) {
  if (pattern_revision_ == other.pattern_revision_ && row_start_ == other.row_start_ &&
      columns_ == other.columns_) {
    return;
  }
  pattern_revision_ = other.pattern_revision_;
  copy_growing(other.row_start_, row_start_);
  copy_growing(other.columns_, columns_);
  copy_growing(other.diagonal_, diagonal_);
  zero_values();
}

void BlockSparseMatrix::zero_values() {
  // A cut adds a few blocks per frame: growing by exactly that would reallocate (and fault in
  // fresh pages for) the whole array every frame, a cost of the body's size. Grow with slack.
  if (values_.capacity() < columns_.size()) {
    values_.reserve(columns_.size() + columns_.size() / 4);
  }
  values_.resize(columns_.size());
  std::fill(values_.begin(), values_.end(), Mat3::Zero());
}

std::size_t BlockSparseMatrix::find(VertexId row, VertexId column) const {
  const auto begin = columns_.begin() + static_cast<std::ptrdiff_t>(row_start_[row]);
  const auto end = columns_.begin() + static_cast<std::ptrdiff_t>(row_start_[row + 1]);
  const auto it = std::lower_bound(begin, end, column);
  INCISE_ASSERT(it != end && *it == column, "block outside the matrix pattern");
  return static_cast<std::size_t>(it - columns_.begin());
}

void BlockSparseMatrix::set_zero() {
  std::fill(values_.begin(), values_.end(), Mat3::Zero());
}

namespace {

/// One row after another, Eigen's 3x3 block times vector.
void multiply_rows_portable(const Mat3* values, const VertexId* columns,
                            const std::size_t* row_start, std::size_t begin, std::size_t end,
                            const Vec3* p, Vec3* out) {
  for (std::size_t i = begin; i < end; ++i) {
    Vec3 sum = Vec3::Zero();
    for (std::size_t k = row_start[i]; k < row_start[i + 1]; ++k) {
      sum.noalias() += values[k] * p[columns[k]];
    }
    out[i - begin] = sum;
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_HAVE_AVX2_ROWS 1

// Written by hand because Eigen picks its SIMD width when compiled, and the portable build
// (SSE2) would leave AVX2/FMA unused on the machines that have it; a product is a third
// faster this way (BENCHMARKS.md). A column-major 3x3 block is nine contiguous doubles, so
// columns 0 and 1 are the first three lanes of 4-wide loads at offsets 0 and 3, and column 2
// is the last three lanes of the load at offset 5 (no load reads past the block); that
// column is summed in its own register and shifted into place once per row.
__attribute__((target("avx2,fma"))) void multiply_rows_avx2(const Mat3* blocks,
                                                            const VertexId* columns,
                                                            const std::size_t* row_start,
                                                            std::size_t begin, std::size_t end,
                                                            const Vec3* p, Vec3* out) {
  const double* values = blocks->data();
  for (std::size_t i = begin; i < end; ++i) {
    __m256d first = _mm256_setzero_pd();
    __m256d second = _mm256_setzero_pd();
    __m256d third_shifted = _mm256_setzero_pd();
    for (std::size_t k = row_start[i]; k < row_start[i + 1]; ++k) {
      const double* a = values + 9 * k;
      const double* q = p[columns[k]].data();
      first = _mm256_fmadd_pd(_mm256_loadu_pd(a), _mm256_broadcast_sd(q), first);
      second = _mm256_fmadd_pd(_mm256_loadu_pd(a + 3), _mm256_broadcast_sd(q + 1), second);
      third_shifted =
          _mm256_fmadd_pd(_mm256_loadu_pd(a + 5), _mm256_broadcast_sd(q + 2), third_shifted);
    }
    alignas(32) double sum[4];
    alignas(32) double third[4];
    _mm256_store_pd(sum, _mm256_add_pd(first, second));
    _mm256_store_pd(third, third_shifted);
    out[i - begin] = Vec3(sum[0] + third[1], sum[1] + third[2], sum[2] + third[3]);
  }
}

bool cpu_has_avx2_fma() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}
#endif

}  // namespace

void BlockSparseMatrix::multiply_rows(std::size_t begin, std::size_t end, std::span<const Vec3> p,
                                      Vec3* out) const {
  INCISE_ASSERT(end <= rows() && p.size() >= rows(), "product outside the matrix");
#ifdef INCISE_HAVE_AVX2_ROWS
  static const bool avx2 = cpu_has_avx2_fma();  // a property of the machine, asked once
  if (avx2) {
    multiply_rows_avx2(values_.data(), columns_.data(), row_start_.data(), begin, end, p.data(),
                       out);
    return;
  }
#endif
  multiply_rows_portable(values_.data(), columns_.data(), row_start_.data(), begin, end, p.data(),
                         out);
}

template <typename Store>
void BlockSparseMatrix::for_each_row_product(std::span<const Vec3> p, const Store& store) const {
  parallel_for(0, rows(), 512, [&](std::size_t first, std::size_t last) {
    Vec3 sums[512];
    for (std::size_t begin = first; begin < last; begin += 512) {
      const std::size_t end = std::min(last, begin + 512);
      multiply_rows(begin, end, p, sums);
      for (std::size_t i = begin; i < end; ++i) {
        store(i, sums[i - begin]);
      }
    }
  });
}

void BlockSparseMatrix::multiply(std::span<const Vec3> p, std::span<Vec3> y) const {
  for_each_row_product(p, [&](std::size_t i, const Vec3& sum) { y[i] = sum; });
}

void BlockSparseMatrix::multiply_add(double scale, std::span<const Vec3> p,
                                     std::span<Vec3> y) const {
  for_each_row_product(p, [&](std::size_t i, const Vec3& sum) { y[i] += scale * sum; });
}

}  // namespace incise
