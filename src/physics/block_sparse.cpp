#include "incise/physics/block_sparse.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

void BlockSparseMatrix::build_pattern(const TetMesh& mesh) {
  const std::size_t n = mesh.vertex_count();
  row_start_.assign(n + 1, 0);
  for (std::size_t v = 0; v < n; ++v) {
    row_start_[v + 1] = 1;  // the diagonal
  }
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& ends = mesh.edge(static_cast<EdgeId>(e));
    ++row_start_[ends[0] + 1];
    ++row_start_[ends[1] + 1];
  }
  for (std::size_t v = 0; v < n; ++v) {
    row_start_[v + 1] += row_start_[v];
  }
  columns_.resize(row_start_[n]);
  std::vector<std::size_t> fill(row_start_.begin(), row_start_.end() - 1);
  for (std::size_t v = 0; v < n; ++v) {
    columns_[fill[v]++] = static_cast<VertexId>(v);
  }
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& ends = mesh.edge(static_cast<EdgeId>(e));
    columns_[fill[ends[0]]++] = ends[1];
    columns_[fill[ends[1]]++] = ends[0];
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

void BlockSparseMatrix::multiply(std::span<const Vec3> p, std::span<Vec3> y) const {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows(), 512),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        Vec3 sum = Vec3::Zero();
                        for (std::size_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
                          sum.noalias() += values_[k] * p[columns_[k]];
                        }
                        y[i] = sum;
                      }
                    });
}

void BlockSparseMatrix::multiply_add(double scale, std::span<const Vec3> p,
                                     std::span<Vec3> y) const {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows(), 512),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        Vec3 sum = Vec3::Zero();
                        for (std::size_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
                          sum.noalias() += values_[k] * p[columns_[k]];
                        }
                        y[i] += scale * sum;
                      }
                    });
}

}  // namespace incise
