#include "incise/physics/block_sparse.hpp"

#include <algorithm>
#include <array>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "incise/core/cpu_features.hpp"
#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/mesh/vertex_graph.hpp"

namespace incise {

BlockSparseMatrix::BlockSparseMatrix() : pattern_(std::make_shared<BlockPattern>()) {}

void BlockSparseMatrix::build_pattern(const TetMesh& mesh) {
  build_pattern(vertex_graph(mesh));
}

void BlockSparseMatrix::build_pattern(const VertexGraph& graph) {
  const std::size_t n = graph.row_start.size() - 1;
  auto pattern = std::make_shared<BlockPattern>();
  pattern->version = pattern_->version + 1;
  // Each row: the diagonal and the neighbours, sorted (products then walk p in order, and
  // find() bisects).
  std::vector<VertexId> row;
  pattern->columns.assign(n, [&](std::size_t v) -> std::span<const VertexId> {
    const auto neighbours = graph.neighbors(static_cast<VertexId>(v));
    row.assign(1, static_cast<VertexId>(v));
    row.insert(row.end(), neighbours.begin(), neighbours.end());
    std::sort(row.begin(), row.end());
    return row;
  });
  pattern_ = std::move(pattern);
  pattern_->diagonal.resize(n);
  for (std::size_t v = 0; v < n; ++v) {
    pattern_->diagonal[v] = find(static_cast<VertexId>(v), static_cast<VertexId>(v));
  }
  values_.clear();
  fit_values();
}

void BlockSparseMatrix::match_pattern(const BlockSparseMatrix& other) {
  if (pattern_ != other.pattern_) {
    pattern_ = other.pattern_;
    values_.clear();
  }
  fit_values();
}

void BlockSparseMatrix::fit_values() {
  // New blocks zero; capacity kept so an edit does not copy the whole matrix (core/growth.hpp).
  resize_keeping(values_, pattern_->columns.storage().size(), capacity_for_moved_rows,
                 Mat3(Mat3::Zero()));
}

void BlockSparseMatrix::zero_values() {
  fit_values();
  std::fill(values_.begin(), values_.end(), Mat3::Zero());
}

void BlockSparseMatrix::add_rows(std::size_t rows) {
  BlockPattern& pattern = *pattern_;
  const std::size_t old_rows = pattern.columns.rows();
  if (rows <= old_rows) {
    return;
  }
  pattern.columns.add_rows(rows);
  pattern.diagonal.resize(rows);
  for (std::size_t v = old_rows; v < rows; ++v) {
    const auto row = static_cast<VertexId>(v);
    pattern.columns.set_row(v, std::span<const VertexId>(&row, 1));
    pattern.diagonal[v] = pattern.columns.begin()[v];
  }
  ++pattern.version;
  fit_values();
}

void BlockSparseMatrix::edit_row(VertexId row, std::span<const VertexId> sorted_columns) {
  BlockPattern& pattern = *pattern_;
  const auto r = static_cast<std::size_t>(row);
  INCISE_ASSERT(r < pattern.columns.rows(), "edit_row: no such row");
  INCISE_ASSERT(std::is_sorted(sorted_columns.begin(), sorted_columns.end()) &&
                    std::binary_search(sorted_columns.begin(), sorted_columns.end(), row),
                "edit_row: columns must be sorted and hold the diagonal");
  if (!pattern.columns.set_row(r, sorted_columns)) {
    return;
  }
  pattern.diagonal[r] = find(row, row);
  ++pattern.version;
  fit_values();
}

bool BlockSparseMatrix::compact_if_fragmented() {
  BlockPattern& pattern = *pattern_;
  if (!pattern.columns.compact_if_fragmented()) {
    return false;
  }
  for (std::size_t v = 0; v < pattern.columns.rows(); ++v) {
    pattern.diagonal[v] = find(static_cast<VertexId>(v), static_cast<VertexId>(v));
  }
  ++pattern.version;
  values_.clear();
  fit_values();
  return true;
}

std::optional<std::size_t> BlockSparseMatrix::find_if_coupled(VertexId row, VertexId column) const {
  const std::span<const VertexId> columns = row_columns(row);
  const auto it = std::lower_bound(columns.begin(), columns.end(), column);
  if (it == columns.end() || *it != column) {
    return std::nullopt;
  }
  return pattern_->columns.begin()[static_cast<std::size_t>(row)] +
         static_cast<std::size_t>(it - columns.begin());
}

std::size_t BlockSparseMatrix::find(VertexId row, VertexId column) const {
  const std::optional<std::size_t> index = find_if_coupled(row, column);
  INCISE_ASSERT(index.has_value(), "block outside the matrix pattern");
  return *index;
}

void BlockSparseMatrix::set_zero() {
  std::fill(values_.begin(), values_.end(), Mat3::Zero());
}

namespace {

/// One row after another, Eigen's 3x3 block times vector. `values` holds 9 numbers per block,
/// column-major: the matrix's own doubles or its single-precision copy (widened to double).
template <typename Scalar>
void multiply_rows_portable(const Scalar* values, const VertexId* columns,
                            const std::size_t* row_begin, const std::size_t* row_end,
                            std::size_t begin, std::size_t end, const Vec3* p, Vec3* out) {
  for (std::size_t i = begin; i < end; ++i) {
    Vec3 sum = Vec3::Zero();
    for (std::size_t k = row_begin[i]; k < row_end[i]; ++k) {
      const Eigen::Map<const Eigen::Matrix<Scalar, 3, 3>> block(values + 9 * k);
      sum.noalias() += block.template cast<double>() * p[columns[k]];
    }
    out[i - begin] = sum;
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_HAVE_AVX2_ROWS 1

/// Four numbers of a block from offset `a` as doubles (a float load widened).
__attribute__((target("avx2,fma"))) inline __m256d load4(const double* a) {
  return _mm256_loadu_pd(a);
}
__attribute__((target("avx2,fma"))) inline __m256d load4(const float* a) {
  return _mm256_cvtps_pd(_mm_loadu_ps(a));
}

// Written by hand because Eigen picks its SIMD width when compiled, and the portable build
// (SSE2) would leave AVX2/FMA unused on the machines that have it; a product is a third
// faster this way (BENCHMARKS.md). A column-major 3x3 block is nine contiguous numbers, so
// columns 0 and 1 are the first three lanes of 4-wide loads at offsets 0 and 3, and column 2
// is the last three lanes of the load at offset 5 (no load reads past the block); that
// column is summed in its own register and shifted into place once per row.
template <typename Scalar>
__attribute__((target("avx2,fma"))) void multiply_rows_avx2(
    const Scalar* values, const VertexId* columns, const std::size_t* row_begin,
    const std::size_t* row_end, std::size_t begin, std::size_t end, const Vec3* p, Vec3* out) {
  for (std::size_t i = begin; i < end; ++i) {
    __m256d first = _mm256_setzero_pd();
    __m256d second = _mm256_setzero_pd();
    __m256d third_shifted = _mm256_setzero_pd();
    for (std::size_t k = row_begin[i]; k < row_end[i]; ++k) {
      const Scalar* a = values + 9 * k;
      const double* q = p[columns[k]].data();
      first = _mm256_fmadd_pd(load4(a), _mm256_broadcast_sd(q), first);
      second = _mm256_fmadd_pd(load4(a + 3), _mm256_broadcast_sd(q + 1), second);
      third_shifted = _mm256_fmadd_pd(load4(a + 5), _mm256_broadcast_sd(q + 2), third_shifted);
    }
    alignas(32) double sum[4];
    alignas(32) double third[4];
    _mm256_store_pd(sum, _mm256_add_pd(first, second));
    _mm256_store_pd(third, third_shifted);
    out[i - begin] = Vec3(sum[0] + third[1], sum[1] + third[2], sum[2] + third[3]);
  }
}

#endif

/// Rows begin..end of the product with the blocks in `values` (either precision): the AVX2
/// kernel where the CPU has it, else the portable one.
template <typename Scalar>
void multiply_rows_of(const Scalar* values, const BlockPattern& pattern, std::size_t begin,
                      std::size_t end, const Vec3* p, Vec3* out) {
  const VertexId* columns = pattern.columns.storage().data();
  const std::size_t* row_begin = pattern.columns.begin().data();
  const std::size_t* row_end = pattern.columns.end().data();
#ifdef INCISE_HAVE_AVX2_ROWS
  if (cpu_has_avx2_fma()) {
    multiply_rows_avx2(values, columns, row_begin, row_end, begin, end, p, out);
    return;
  }
#endif
  multiply_rows_portable(values, columns, row_begin, row_end, begin, end, p, out);
}

/// y[m] = A p[m] for every m, with the blocks in `values` (either precision): chunk by chunk
/// of rows, every vector passing while the chunk's blocks stay in the core's own cache (the
/// same bytes in either precision: about 140 kB on a tetrahedral mesh's rows), each through
/// the row kernel, so every product has the same bits as one alone.
template <typename Scalar>
void multiply_several_of(const Scalar* values, const BlockPattern& pattern, std::size_t rows,
                         std::span<const std::span<const Vec3>> p,
                         std::span<const std::span<Vec3>> y) {
  constexpr std::size_t kChunkRows = 1024 / sizeof(Scalar);  // 256 in float, 128 in double
  parallel_for(0, rows, kChunkRows, [&](std::size_t first, std::size_t last) {
    for (std::size_t begin = first; begin < last; begin += kChunkRows) {
      const std::size_t end = std::min(last, begin + kChunkRows);
      for (std::size_t m = 0; m < p.size(); ++m) {
        multiply_rows_of(values, pattern, begin, end, p[m].data(), y[m].data() + begin);
      }
    }
  });
}

}  // namespace

void BlockSparseMatrix::multiply_rows(std::size_t begin, std::size_t end, std::span<const Vec3> p,
                                      Vec3* out) const {
  INCISE_ASSERT(end <= rows() && p.size() >= rows(), "product outside the matrix");
  INCISE_ASSERT(values_.size() == pattern_->columns.storage().size(),
                "product with a matrix that has not matched its pattern since an edit");
  multiply_rows_of(values_.data()->data(), *pattern_, begin, end, p.data(), out);
}

void BlockSparseMatrix::refresh_single_precision() {
  const std::size_t count = 9 * values_.size();
  resize_keeping(single_values_, count, capacity_for_moved_rows);
  const double* source = values_.data()->data();
  float* target = single_values_.data();
  parallel_for(0, count, 1 << 15, [&](std::size_t first, std::size_t last) {
    for (std::size_t s = first; s != last; ++s) {
      target[s] = static_cast<float>(source[s]);
    }
  });
}

void BlockSparseMatrix::multiply_rows_single(std::size_t begin, std::size_t end,
                                             std::span<const Vec3> p, Vec3* out) const {
  INCISE_ASSERT(end <= rows() && p.size() >= rows(), "product outside the matrix");
  INCISE_ASSERT(single_values_.size() == 9 * values_.size(),
                "single-precision product before refresh_single_precision");
  multiply_rows_of(single_values_.data(), *pattern_, begin, end, p.data(), out);
}

void BlockSparseMatrix::multiply_several_single(std::span<const std::span<const Vec3>> p,
                                                std::span<const std::span<Vec3>> y) const {
  INCISE_ASSERT(p.size() == y.size(), "multiply_several_single: as many products as vectors");
  INCISE_ASSERT(single_values_.size() == 9 * values_.size(),
                "single-precision product before refresh_single_precision");
  for (std::size_t m = 0; m < p.size(); ++m) {
    INCISE_ASSERT(p[m].size() >= rows() && y[m].size() >= rows(), "product outside the matrix");
  }
  multiply_several_of(single_values_.data(), *pattern_, rows(), p, y);
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

void BlockSparseMatrix::multiply_several(std::span<const std::span<const Vec3>> p,
                                         std::span<const std::span<Vec3>> y) const {
  INCISE_ASSERT(p.size() == y.size(), "multiply_several: as many products as vectors");
  INCISE_ASSERT(values_.size() == pattern_->columns.storage().size(),
                "product with a matrix that has not matched its pattern since an edit");
  for (std::size_t m = 0; m < p.size(); ++m) {
    INCISE_ASSERT(p[m].size() >= rows() && y[m].size() >= rows(), "product outside the matrix");
  }
  if (values_.empty()) {
    return;  // no rows (and no block whose numbers to point at)
  }
  multiply_several_of(values_.data()->data(), *pattern_, rows(), p, y);
}

void BlockSparseMatrix::multiply_add(double scale, std::span<const Vec3> p,
                                     std::span<Vec3> y) const {
  for_each_row_product(p, [&](std::size_t i, const Vec3& sum) { y[i] += scale * sum; });
}

}  // namespace incise
