#pragma once
// A sparse matrix of 3x3 blocks, one block row per vertex and a block for every pair of
// vertices joined by a mesh edge (and the diagonal): the shape of every stiffness, damping and
// system matrix in incise. Both triangles are stored, so a product is one pass over the rows,
// parallel and deterministic (each row is summed in a fixed order by one thread).

#include <cstdint>
#include <span>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/mesh/vertex_graph.hpp"

namespace incise {

class TetMesh;

class BlockSparseMatrix {
 public:
  /// Builds the pattern from the mesh's edges; values become zero.
  void build_pattern(const TetMesh& mesh);
  /// The same from a vertex graph already at hand (taken at the mesh's current revision).
  void build_pattern(const VertexGraph& graph, std::uint64_t revision);
  /// Copies another matrix's pattern (values zero) unless it is already the same.
  void match_pattern(const BlockSparseMatrix& other);
  /// Sets every stored block to zero (keeping the storage).
  void zero_values();
  /// Mesh revision the pattern was built for.
  [[nodiscard]] std::uint64_t pattern_revision() const { return pattern_revision_; }

  [[nodiscard]] std::size_t rows() const { return row_start_.empty() ? 0 : row_start_.size() - 1; }
  [[nodiscard]] std::size_t block_count() const { return columns_.size(); }
  [[nodiscard]] std::span<const std::size_t> row_start() const { return row_start_; }
  [[nodiscard]] std::span<const VertexId> columns() const { return columns_; }
  [[nodiscard]] std::span<Mat3> values() { return values_; }
  [[nodiscard]] std::span<const Mat3> values() const { return values_; }
  /// Index of block (row, column) in values(); asserts that it is in the pattern.
  [[nodiscard]] std::size_t find(VertexId row, VertexId column) const;
  [[nodiscard]] std::size_t diagonal(VertexId row) const { return diagonal_[row]; }

  void set_zero();
  /// y = A p (parallel over rows; the result does not depend on the thread count).
  void multiply(std::span<const Vec3> p, std::span<Vec3> y) const;
  /// y += scale A p.
  void multiply_add(double scale, std::span<const Vec3> p, std::span<Vec3> y) const;
  /// out[i - begin] = (A p)_i for begin <= i < end, on the calling thread: the kernel under
  /// every product, for callers that fuse other per-row work into the same pass.
  void multiply_rows(std::size_t begin, std::size_t end, std::span<const Vec3> p, Vec3* out) const;

 private:
  /// store(row, (A p)_row) for every row, rows in parallel.
  template <typename Store>
  void for_each_row_product(std::span<const Vec3> p, const Store& store) const;

  std::uint64_t pattern_revision_ = ~std::uint64_t{0};
  std::vector<std::size_t> row_start_;
  std::vector<VertexId> columns_;
  std::vector<std::size_t> diagonal_;
  std::vector<Mat3> values_;
};

}  // namespace incise
