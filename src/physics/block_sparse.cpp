#include "incise/physics/block_sparse.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/mesh/vertex_graph.hpp"

namespace incise {

void BlockSparseMatrix::build_pattern(const TetMesh& mesh) {
  const std::size_t n = mesh.vertex_count();
  const VertexGraph graph = vertex_graph(mesh);
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
  values_.assign(columns_.size(), Mat3::Zero());
  pattern_revision_ = mesh.revision();
}

void BlockSparseMatrix::match_pattern(const BlockSparseMatrix& other) {
  if (pattern_revision_ == other.pattern_revision_ && row_start_ == other.row_start_ &&
      columns_ == other.columns_) {
    return;
  }
  pattern_revision_ = other.pattern_revision_;
  row_start_ = other.row_start_;
  columns_ = other.columns_;
  diagonal_ = other.diagonal_;
  values_.assign(columns_.size(), Mat3::Zero());
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

template <typename Store>
void BlockSparseMatrix::for_each_row_product(std::span<const Vec3> p, const Store& store) const {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows(), 512),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        Vec3 sum = Vec3::Zero();
                        for (std::size_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
                          sum.noalias() += values_[k] * p[columns_[k]];
                        }
                        store(i, sum);
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
