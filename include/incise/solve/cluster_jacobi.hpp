#pragma once
// Block-Jacobi over clusters of strongly coupled vertices: vertices joined by a strong block
// of the matrix (|A_ij| above a fraction of sqrt(|A_ii| |A_jj|), Frobenius norms) are grouped,
// a few at most, and each group's diagonal block is inverted whole.
//
// Why: a subdivision cut leaves slivers (nearly flat tetrahedra). A sliver's stiffness across
// its thickness is huge, so its corners' diagonal blocks are too, and a motion of the corners
// together, which that stiffness does not resist, looks nearly free to a per-vertex
// block-Jacobi: CG needs 2-6x the iterations of the uncut body (52 -> 257 on the peers' box,
// 10^3 cells, cut along a plane of vertices). Inverting the corners' block together removes
// those modes.
//
// Threads: update() and apply() run their loops on the worker pool; the result does not
// depend on the thread count.

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/core/types.hpp"
#include "incise/physics/block_sparse.hpp"

namespace incise {

/// How ClusterJacobi groups strongly coupled vertices.
struct ClusterOptions {
  /// A block is strong when |A_ij| > threshold sqrt(|A_ii| |A_jj|). A regular tetrahedral
  /// mesh has couplings below 0.3; a sliver's corners about 1/3 and above.
  double threshold = 0.3;
  std::size_t max_size = 8;  ///< vertices per cluster at most
};

/// Block-Jacobi over clusters: vertices strongly coupled to each other (a cut's slivers) are
/// inverted together as one block; the two-level preconditioner's smoother.
class ClusterJacobi {
 public:
  /// Groups by `options` from the first update() on.
  explicit ClusterJacobi(const ClusterOptions& options = {});

  /// Groups the free vertices again when the pattern or the held rows changed, then inverts
  /// each group's diagonal block from the matrix's current values. False when a block is not
  /// positive definite.
  [[nodiscard]] bool update(const BlockSparseMatrix& matrix, std::span<const char> constrained);
  /// The inverse diagonal block of each vertex alone in its cluster (zero for held vertices
  /// and for those in clusters of two or more, which apply_clusters() handles).
  [[nodiscard]] std::span<const Mat3> single_inverse() const { return single_inverse_; }
  /// z = the inverse cluster block times r on the vertices of clusters of two or more;
  /// returns their part of r.z, summed in a fixed order.
  double apply_clusters(std::span<const Vec3> r, std::span<Vec3> z) const;

  [[nodiscard]] std::size_t cluster_count() const { return first_.size() - 1; }  ///< clusters
  /// Vertices in clusters of two or more.
  [[nodiscard]] std::size_t clustered_vertices() const { return clustered_vertices_; }
  /// The grouping, which follows the cuts step by step (a checkpoint): what update() then
  /// does next is what it would have done. The inverses are made again from the next matrix.
  void save_state(StateWriter& out) const;
  void load_state(StateReader& in);  ///< restores what save_state() wrote
  /// Vertex lists of the clusters, packed: members()[first[c] .. first[c + 1]).
  [[nodiscard]] std::span<const VertexId> members() const { return members_; }
  /// Where each cluster's members start in members(), and one past the last.
  [[nodiscard]] std::span<const std::size_t> first() const { return first_; }

 private:
  /// Groups the vertices into clusters, then packs them: all of them for first_new = 0; else
  /// (an edit that added vertices first_new and above) the new vertices and the members of
  /// every cluster that holds a vertex coupled to a new one, the rest kept as they were.
  void group(const BlockSparseMatrix& matrix, std::span<const char> constrained,
             std::size_t first_new);
  /// Joins the strong pairs with an end in `regroup` (alone in its cluster on entry).
  void join_strong_pairs(const BlockSparseMatrix& matrix, std::span<const char> constrained,
                         std::span<const char> regroup);
  /// The packed lists and block places of the clusters the union-find holds.
  void pack(const BlockSparseMatrix& matrix, std::span<const char> constrained);
  VertexId root(VertexId v);

  ClusterOptions options_;
  std::shared_ptr<const BlockPattern> pattern_;
  std::uint64_t pattern_version_ = 0;
  std::vector<char> constrained_;
  std::vector<VertexId> parent_;  ///< union-find over vertices: the clusters
  std::vector<std::size_t> size_;
  std::vector<VertexId> members_;
  std::vector<std::size_t> first_{0};
  std::vector<Mat3> single_inverse_;
  /// Clusters of two or more vertices: members()[first[c] .. first[c + 1]) of cluster
  /// multi_[m], the inverse of its (3k x 3k) block, dense and column-major, at
  /// inverse_[offset_[m]], and the storage index of its blocks (a, b), a-major, from
  /// block_first_[m] (kNoBlock where two members are not coupled).
  std::vector<std::size_t> multi_;
  std::vector<std::size_t> offset_;
  std::vector<double> inverse_;
  std::vector<std::size_t> block_of_;
  std::vector<std::size_t> block_first_;
  std::size_t largest_ = 1;  ///< vertices in the largest cluster
  std::size_t clustered_vertices_ = 0;
};

}  // namespace incise
