#pragma once
// A sparse matrix of 3x3 blocks, one block row per vertex and a block for every pair of
// vertices joined by a mesh edge (and the diagonal): the shape of every stiffness, damping and
// system matrix in incise. Both triangles are stored, so a product is one pass over the rows,
// parallel and deterministic (each row is summed in a fixed order by one thread).

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "incise/core/packed_rows.hpp"
#include "incise/core/types.hpp"
#include "incise/mesh/vertex_graph.hpp"

namespace incise {

class TetMesh;

/// Where each block row lives in a matrix's storage, shared by every matrix of that shape:
/// sorted columns per row, packed so that an edit rewrites only the rows it touched (a row
/// that grows moves to the end of the storage; see PackedRows).
struct BlockPattern {
  PackedRows<VertexId> columns;       ///< each row's sorted columns (vertices)
  std::vector<std::size_t> diagonal;  ///< storage index of each row's diagonal block
  std::uint64_t version = 0;          ///< bumped on every change
};

/// The block matrix: values over a BlockPattern that several matrices of one body may share.
/// One thread edits it; products read it from worker threads.
class BlockSparseMatrix {
 public:
  BlockSparseMatrix();
  /// Builds the pattern from the mesh's edges; values become zero.
  void build_pattern(const TetMesh& mesh);
  /// The same from a vertex graph already at hand. A fresh pattern: matrices that shared the
  /// old one keep it until they match this one.
  void build_pattern(const VertexGraph& graph);
  /// Shares another matrix's pattern (an O(1) handover, however large the matrix); values
  /// become zero when the pattern is another one, and storage the pattern grew by since this
  /// matrix last matched it starts zero (edited rows are unspecified). The pattern is
  /// then edited through either matrix (edit_row, add_rows, compact) for both: only the model
  /// that owns the mesh's pattern edits it, and other matrices match it again before use.
  void match_pattern(const BlockSparseMatrix& other);
  /// Sets every stored block to zero (keeping the storage).
  void zero_values();
  /// Changes whenever the pattern changes (a build or any edit); with pattern(), tells whether
  /// two looks saw the same pattern (holding the pointer keeps its address from being reused).
  [[nodiscard]] std::uint64_t pattern_version() const { return pattern_->version; }
  /// The pattern, shared with every matrix that matched it.
  [[nodiscard]] std::shared_ptr<const BlockPattern> pattern() const { return pattern_; }

  // ---- edits after a mesh edit (values of edited rows are left unspecified) --------------
  /// Appends rows up to `rows`; each new row holds only its diagonal block.
  void add_rows(std::size_t rows);
  /// Gives `row` these columns (sorted, the row itself among them). In place when they fit,
  /// else the row moves to the end of the storage. Blocks of other rows keep their places.
  void edit_row(VertexId row, std::span<const VertexId> sorted_columns);
  /// Packs the rows again in vertex order once the storage left behind by moved rows reaches
  /// a quarter of the whole. True when it did (every block then has a new place).
  bool compact_if_fragmented();

  /// Block rows, one per vertex.
  [[nodiscard]] std::size_t rows() const { return pattern_->columns.rows(); }
  /// Blocks in rows (what a product multiplies).
  [[nodiscard]] std::size_t block_count() const { return pattern_->columns.live(); }
  /// Row i's blocks are values()[row_begin()[i] .. row_end()[i]).
  [[nodiscard]] std::span<const std::size_t> row_begin() const { return pattern_->columns.begin(); }
  /// Each row's end in values(), as row_begin.
  [[nodiscard]] std::span<const std::size_t> row_end() const { return pattern_->columns.end(); }
  /// The column of every stored block, beside values().
  [[nodiscard]] std::span<const VertexId> columns() const { return pattern_->columns.storage(); }
  /// A row's columns, sorted.
  [[nodiscard]] std::span<const VertexId> row_columns(VertexId row) const {
    return pattern_->columns.row(static_cast<std::size_t>(row));
  }
  /// The whole storage, including what rows left behind (never read by products).
  [[nodiscard]] std::span<Mat3> values() { return values_; }
  /// The same, read only.
  [[nodiscard]] std::span<const Mat3> values() const { return values_; }
  /// Index of block (row, column) in values(); asserts that it is in the pattern.
  [[nodiscard]] std::size_t find(VertexId row, VertexId column) const;
  /// The same, or nothing when the two vertices are not coupled.
  [[nodiscard]] std::optional<std::size_t> find_if_coupled(VertexId row, VertexId column) const;
  /// Index of a row's diagonal block in values().
  [[nodiscard]] std::size_t diagonal(VertexId row) const { return pattern_->diagonal[row]; }

  /// Sets every stored block to zero, as zero_values.
  void set_zero();
  /// y = A p (parallel over rows; the result does not depend on the thread count).
  void multiply(std::span<const Vec3> p, std::span<Vec3> y) const;
  /// y += scale A p.
  void multiply_add(double scale, std::span<const Vec3> p, std::span<Vec3> y) const;
  /// y[m] = A p[m] for several vectors at once, reading the matrix once for every four of them
  /// (a product of a large body is limited by memory bandwidth). Rows in parallel, each summed
  /// in a fixed order: the result does not depend on the thread count.
  void multiply_several(std::span<const std::span<const Vec3>> p,
                        std::span<const std::span<Vec3>> y) const;
  /// out[i - begin] = (A p)_i for begin <= i < end, on the calling thread: the kernel under
  /// every product, for callers that fuse other per-row work into the same pass.
  void multiply_rows(std::size_t begin, std::size_t end, std::span<const Vec3> p, Vec3* out) const;

  // ---- single-precision copy, for products that read half the bytes ------------------------
  /// Copies the values, rounded to float, into the single-precision copy (a pass over the
  /// storage). Call after the values change and before multiply_rows_single.
  void refresh_single_precision();
  /// As multiply_rows, with the blocks read from the single-precision copy (sums in double).
  /// Products of large bodies are limited by memory bandwidth, so half the bytes is nearly
  /// twice the speed; each block differs from the double one by at most 2^-24 of each entry.
  void multiply_rows_single(std::size_t begin, std::size_t end, std::span<const Vec3> p,
                            Vec3* out) const;
  /// As multiply_several, with the blocks read from the single-precision copy: each chunk of
  /// rows is read from memory once and from cache for the other vectors.
  void multiply_several_single(std::span<const std::span<const Vec3>> p,
                               std::span<const std::span<Vec3>> y) const;

 private:
  /// store(row, (A p)_row) for every row, rows in parallel.
  template <typename Store>
  void for_each_row_product(std::span<const Vec3> p, const Store& store) const;
  /// Sizes the values to the pattern's storage; new storage is zero.
  void fit_values();

  std::shared_ptr<BlockPattern> pattern_;
  std::vector<Mat3> values_;
  std::vector<float> single_values_;  ///< 9 per block, column-major as values_
};

}  // namespace incise
