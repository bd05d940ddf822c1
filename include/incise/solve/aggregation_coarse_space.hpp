#pragma once
// The coarse level of the two-level preconditioner ("two-level"): vertices grouped into
// aggregates of a vertex and its neighbours (Vanek, Mandel and Brezina's greedy aggregation),
// each aggregate moving as one rigid body: three translations and three rotations about its
// centre at the positions where the matrix was linearised (the near-kernel of elasticity;
// with translations alone CG needed more iterations, see BENCHMARKS.md). Each aggregate's six
// modes are orthonormalised over its members, and a mode its members cannot carry (the
// rotation about the line through two vertices, any rotation of one vertex) is dropped. CG adds the
// coarse correction to the clusters' block-Jacobi one (additive Schwarz). On a small body the
// coarse matrix P^T A P is factorised exactly: P (P^T A P)^-1 P^T r. Above 1,000 coarse unknowns
// its exact solve would cost more than a product at every iteration (4 ms on the 384k-tet box), so
// the coarse system is solved by one symmetric V-cycle over groups of aggregates, groups of
// those groups, and so on until a level is small enough to factorise (src/solve/coarse_cycle.hpp).
// The V-cycle replaced an additive correction (own blocks plus one level of groups) that left
// most of the coarse error: CG needed 110 iterations on the 384k box from a cold start where an
// exact coarse solve needs 56 (BENCHMARKS.md).
//
// Why: block-Jacobi CG needs iterations in proportion to the mesh's resolution (47 / 99 / 209
// on the peers' box at n = 10 / 20 / 40) and twice as many on a body that a cut has set free
// (slivers, pieces that hang). The coarse level carries the smooth part of the error, which
// point smoothing moves only one ring of vertices per iteration. Written here because the
// multigrid libraries in Debian (hypre, Trilinos ML) are MPI-based and rebuild their whole
// hierarchy for every matrix, where this one keeps its factor for ten steps and follows a cut
// in between by letting new vertices join their neighbours' aggregates.
//
// Threads: one caller at a time (update()'s Galerkin sum and solve()'s passes run on the worker
// pool, each coarse row, aggregate or group summed by one task: deterministic); correction()
// may be read from any thread between calls.

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/core/types.hpp"
#include "incise/physics/block_sparse.hpp"

namespace incise {

namespace coarse {
class CoarseCycle;
}

/// The two-level preconditioner's coarse level: the free vertices grouped into aggregates
/// that move rigidly (three translations, three rotations), the matrix restricted to those
/// modes and factorised, kept across steps and followed locally after a cut.
class AggregationCoarseSpace {
 public:
  AggregationCoarseSpace();
  /// Coarse unknowns above which levels of groups are used (default 1,000: on the cut 6k-tet box
  /// frames cost 10-15 % less than with 300, the exact solve's iterations outweighing its cost).
  void set_exact_limit(std::size_t unknowns) { exact_limit_ = unknowns; }
  /// Levels of groups above the aggregates through which the coarse system is solved (0: it
  /// is factorised exactly), as of the last aggregation.
  [[nodiscard]] std::size_t group_levels() const;
  /// Nodes on each coarse level, the aggregates first, then each level of groups.
  [[nodiscard]] std::vector<std::size_t> level_sizes() const;
  /// Each node of coarse level k's group on level k + 1 (k below the top; level 0: the
  /// aggregates).
  [[nodiscard]] std::span<const int> group_of(std::size_t level) const;
  /// Calls of update() between factorisations (default 10; 1: every call).
  void set_refactor_every(int updates) { refactor_every_ = std::max(updates, 1); }
  ~AggregationCoarseSpace();
  AggregationCoarseSpace(const AggregationCoarseSpace&) = delete;
  AggregationCoarseSpace& operator=(const AggregationCoarseSpace&) = delete;

  /// Rigid modes per aggregate: three translations, three rotations.
  static constexpr int kModes = 6;
  using Modes = Eigen::Matrix<double, kModes, 1>;            ///< an aggregate's motion in its modes
  using ModeMatrix = Eigen::Matrix<double, kModes, kModes>;  ///< one block of P^T A P
  /// A vertex's rows of the prolongation P, or of its raw rigid coordinates: its displacement
  /// (m) under each coarse mode.
  using VertexModes = Eigen::Matrix<double, 3, kModes>;

  /// Forms P^T A P from the matrix's current values (free rows and columns only) and
  /// factorises it on the first call and every refactor_every() calls after, aggregating the
  /// free vertices again first if the matrix's pattern or the held rows changed, and taking
  /// the rotations about `positions` (m; where the matrix was linearised; empty: translations
  /// only). In between, the factor is kept and new vertices join their neighbours'
  /// aggregates. False if the factorisation fails (A not positive definite on free rows).
  [[nodiscard]] bool update(const BlockSparseMatrix& matrix, std::span<const char> constrained,
                            std::span<const Vec3> positions = {});

  /// Solves the coarse system for the residual r (restricted by P^T); the correction of
  /// vertex i is then correction(i). Returns r.(P e), the correction's part of r.z, as
  /// (P^T r).e. Its passes run on the worker threads, the factorised solve on the caller's.
  double solve(std::span<const Vec3> residual);
  /// Vertices per chunk of the restriction P^T r, whose sums go chunk by chunk in a fixed
  /// order (the same bits on any thread count).
  static constexpr std::size_t kRestrictionChunk = 1024;
  /// The restriction's part from vertices chunk * kRestrictionChunk onwards (one chunk), for
  /// a caller that has just written that part of r (CG's pass that updates it): chunks may be
  /// restricted on different threads at once. Then solve_restricted() as solve() would go on.
  void restrict_chunk(std::size_t chunk, std::span<const Vec3> residual);
  /// solve() for the residual whose every chunk was given to restrict_chunk().
  double solve_restricted();
  /// The coarse correction at vertex i (zero for a held vertex).
  [[nodiscard]] Vec3 correction(std::size_t vertex) const {
    const int aggregate = aggregate_of_[vertex];
    if (aggregate < 0) {
      return Vec3::Zero();
    }
    const Modes& motion = coarse_motion_[static_cast<std::size_t>(aggregate)];
    return motion.head<3>() + motion.tail<3>().cross(offset_[vertex]);
  }

  /// z += P e: each aggregate's correction added to its members.
  void add_correction(std::span<Vec3> z) const;

  [[nodiscard]] std::size_t aggregate_count() const { return members_.size(); }  ///< coarse
  /// Everything the next updates and solves depend on (a checkpoint): the aggregates and
  /// their modes, the coarse matrix as last factorised, how many updates ago, and which
  /// matrix patterns they were built from and last followed. The factor is made again from
  /// the saved matrix, so a resumed run solves exactly as it would have.
  void save_state(StateWriter& out) const;
  void load_state(StateReader& in);  ///< restores what save_state() wrote
  /// The aggregate of each vertex, -1 for held ones.
  [[nodiscard]] std::span<const int> aggregate_of() const { return aggregate_of_; }

 private:
  void aggregate(const BlockSparseMatrix& matrix, std::span<const char> constrained);
  void extend(const BlockSparseMatrix& matrix, std::span<const char> constrained,
              std::span<const Vec3> positions);
  /// members_ from aggregate_of_, each in vertex order, and the restriction's partial sums.
  void collect_members();
  /// partial_of_, chunk_partial_first_ and aggregate_partials_ from aggregate_of_.
  void collect_partials();
  /// Each aggregate's centre and orthonormal modes at `positions`, and every member's offset.
  void shape_modes(std::span<const Vec3> positions);
  /// A vertex's offset from the centre of `aggregate` (m; zero without positions).
  [[nodiscard]] Vec3 offset_in(std::size_t aggregate, std::span<const Vec3> positions,
                               std::size_t vertex) const;

  /// A look at a matrix's pattern and held rows: the pattern by its rows and columns (a hash),
  /// so that a pattern edited back to what it was, compacted, or built again after a resume
  /// from a checkpoint is the same one.
  struct Look {
    bool taken = false;
    std::uint64_t hash = 0;
    std::vector<char> constrained;
  };
  [[nodiscard]] bool same_as(const Look& look, const BlockSparseMatrix& matrix,
                             std::span<const char> constrained);
  void remember(Look& look, const BlockSparseMatrix& matrix, std::span<const char> constrained);
  /// The hash of the matrix's pattern, computed once per pattern version.
  std::uint64_t pattern_hash(const BlockSparseMatrix& matrix);
  /// coarse_slot_ for the matrix's storage, from slots_by_row_ (after the storage moved).
  void place_slots(const BlockSparseMatrix& matrix);
  Look aggregated_;                                     ///< what the aggregates were built from
  Look seen_;                                           ///< what they were last extended to
  std::shared_ptr<const BlockPattern> hashed_pattern_;  ///< held, so its address is not reused
  std::uint64_t hashed_version_ = 0;
  std::uint64_t hashed_value_ = 0;
  /// The coarse slot of each block of the aggregated pattern, row by row in column order (-1
  /// for none): coarse_slot_ independent of where the storage keeps each row.
  std::vector<int> slots_by_row_;
  /// The free vertices' graph of the last aggregation (compressed rows), kept so the next one
  /// is built in pages already mapped.
  std::vector<std::size_t> graph_first_;
  std::vector<int> graph_node_;
  std::vector<double> graph_weight_;
  std::shared_ptr<const BlockPattern> placed_pattern_;  ///< what coarse_slot_ is placed for
  std::uint64_t placed_version_ = 0;
  std::vector<int> aggregate_of_;
  /// The restriction P^T r in two passes: vertices in fixed chunks, in order, each member
  /// added to its aggregate's partial sum for the chunk (partial_of_[v], -1 for held ones;
  /// chunk c's partials at chunk_partial_first_[c] .. [c + 1]); then each aggregate adds its
  /// partials (aggregate_partials_[aggregate_partial_first_[a] .. [a + 1]], in chunk order).
  std::vector<int> partial_of_;
  std::vector<std::size_t> chunk_partial_first_;
  std::vector<std::size_t> aggregate_partial_first_;
  std::vector<int> aggregate_partials_;
  std::vector<Modes> partial_sums_;  ///< solve(): (sum of r_v, sum of d_v x r_v) per partial
  std::vector<std::vector<VertexId>> members_;
  /// For each live block of A (by storage index), its coarse block's slot, or -1.
  std::vector<int> coarse_slot_;
  /// Per vertex: its offset d_v from its aggregate's centre (m), zero for held ones. Its rows
  /// of P are [I, -[d_v]x] W_a, derived where needed: CG's pass reads 24 bytes per vertex.
  std::vector<Vec3> offset_;
  std::vector<Vec3> centre_;  ///< per aggregate (m)
  /// Per aggregate: raw rigid coordinates (translation, rotation about the centre) from its
  /// orthonormal modes; and its modes' coordinates from a raw rigid motion (the pseudo-inverse).
  std::vector<ModeMatrix> modes_from_raw_, raw_from_modes_;
  std::vector<unsigned> dropped_;  ///< per aggregate: modes dropped, bit k for mode k
  /// The coarse system P^T A P (its blocks, by slot) and its solve: exact or a V-cycle.
  std::unique_ptr<coarse::CoarseCycle> cycle_;
  /// Each aggregate's correction as a raw rigid motion W_a e_a (translation, rotation).
  std::vector<Modes> coarse_motion_;
  int refactor_every_ = 10;
  /// Coarse unknowns up to which the aggregates' system is factorised exactly; above, levels of
  /// groups (coarse_cycle.hpp).
  std::size_t exact_limit_ = 1000;
  std::vector<int> slot_row_, slot_column_;  ///< each coarse slot's aggregates (a, b)
  std::vector<double> own_part_;             ///< solve(): each aggregate's part of r.z
  /// solve(), per aggregate in its modes: the right-hand side P^T r and the coarse solution.
  std::vector<Modes> cycle_rhs_, cycle_solution_;
  int updates_since_factor_ = 0;
  bool factored_ = false;
};

}  // namespace incise
