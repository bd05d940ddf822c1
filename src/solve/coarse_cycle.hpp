#pragma once
// The coarse system of the two-level preconditioner, P^T A P y = c in the aggregates' rigid
// modes, and its solve: exact (a sparse Cholesky factor) while it has at most `exact_limit`
// unknowns; above, one symmetric V-cycle over levels of groups. Each level's nodes are grouped
// by up to eight (a node and its first ungrouped neighbours), each group moving rigidly in the
// modes of its members (three translations, three rotations about its centre), until a level
// is small enough to factorise. On each level below the top the cycle smooths with each node's
// own block inverted (damped so the cycle stays positive definite), corrects from the level
// above, and smooths again.
//
// Why a hierarchy and not one level of groups: what the V-cycle misses is its top level's
// coarseness. On the 384k-tet box one level of groups of about 22 aggregates, factorised,
// left CG 84 iterations from a cold start where the exact coarse solve needs 56; groups of at
// most eight there need 74, but their exact solve (2,000 unknowns) is sequential and cost more
// than the iterations saved. Solving those groups by their own V-cycle keeps most of the gain
// at the cost of a few megabytes read per iteration (BENCHMARKS.md, sessions 53-54).
//
// Threads: one caller at a time. assemble()'s and solve()'s passes run on the worker pool,
// each node's or group's sum by one task in a fixed order (the same bits on any thread count);
// the top level's factorised solve runs on the caller's thread.

#include <Eigen/SparseCore>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "incise/core/types.hpp"
#include "quantized_mode_blocks.hpp"
#include "rigid_block_maths.hpp"

namespace incise {

class DirectFactorization;

namespace coarse {

class CoarseCycle {
 public:
  CoarseCycle();
  ~CoarseCycle();
  CoarseCycle(const CoarseCycle&) = delete;
  CoarseCycle& operator=(const CoarseCycle&) = delete;

  /// Nodes per group at most, on each level above the aggregates.
  static constexpr std::size_t kGroupLimit = 8;

  /// The levels above `nodes` aggregates coupled through the slots (slot s couples
  /// slot_row[s] with slot_column[s]; row by row, each row's columns increasing, the pattern
  /// symmetric): groups of groups until a level has at most `exact_limit` unknowns (or one
  /// node). The aggregates' blocks are then written to aggregate_blocks() before assemble().
  void build(std::size_t nodes, std::span<const int> slot_row, std::span<const int> slot_column,
             std::size_t exact_limit);
  /// P^T A P's blocks, slot by slot, in the aggregates' orthonormal modes (dropped modes
  /// filled): written by the caller, read by assemble().
  [[nodiscard]] std::vector<ModeMatrix>& aggregate_blocks() { return levels_.front().blocks; }
  [[nodiscard]] const std::vector<ModeMatrix>& aggregate_blocks() const {
    return levels_.front().blocks;
  }
  /// Every level from the aggregates' blocks, their centres (m) and raw rigid coordinates
  /// from their modes' (modes_from_raw, the pseudo-inverse of their modes): the groups' modes,
  /// each level's matrix, the smoothers, and the top level's factor. False if the
  /// factorisation fails (the matrix not positive definite).
  [[nodiscard]] bool assemble(std::span<const Vec3> centre,
                              std::span<const ModeMatrix> modes_from_raw);
  /// y = B c for the aggregates' right-hand sides c (in their modes): the exact solve, or the
  /// V-cycle (a symmetric positive definite approximation of it).
  void solve(std::span<const Modes> rhs, std::span<Modes> solution);
  /// Levels of groups above the aggregates (0: the aggregates' system is factorised).
  [[nodiscard]] std::size_t group_levels() const { return levels_.size() - 1; }
  /// Nodes on each level, the aggregates first.
  [[nodiscard]] std::vector<std::size_t> level_sizes() const;
  /// Each node of level k's group on level k + 1 (k below the top).
  [[nodiscard]] std::span<const int> group_of(std::size_t k) const { return levels_[k].group_of; }

 private:
  /// One level: its nodes, their matrix in 6x6 blocks (slots row by row, each row's columns
  /// increasing) and, below the top, the smoother and the map to the level above.
  struct Level {
    std::vector<int> slot_row, slot_column;
    std::vector<std::size_t> slot_first;  ///< each node's first slot
    std::vector<int> diagonal_slot;       ///< each node's own block
    std::vector<ModeMatrix> blocks;
    /// Above the aggregates: each node's centre (m; the mean of its members'), its modes'
    /// pseudo-inverse and the modes it drops (bit k for mode k).
    std::vector<Vec3> centre;
    std::vector<ModeMatrix> modes_from_raw;
    std::vector<unsigned> dropped;
    /// Below the top: each node's group on the level above; each group's members in order
    /// (group_member[group_first[g] .. group_first[g + 1]]); each slot's slot above.
    std::vector<int> group_of;
    std::vector<std::size_t> group_first;
    std::vector<int> group_member;
    std::vector<int> group_slot;
    /// Below the top, per node: its modes from its group's (Q), and its damped own inverse
    /// w L (L the inverse of its own block, w the damping that keeps the cycle positive
    /// definite).
    std::vector<ModeMatrix> group_map;
    std::vector<ModeMatrix> own_inverse;
    /// The blocks in 8 bits for the cycle's products (quantized_mode_blocks.hpp: the cycle is a
    /// preconditioner, and the product is bound by memory), block (b, a) the transpose of
    /// (a, b) so both products use one symmetric matrix.
    std::vector<QuantizedModeMatrix> quantized_blocks;
    std::vector<int> mirror_slot;  ///< below the top: each slot (a, b)'s mirror (b, a)
    /// The matrix times the groups' modes, K_ag = sum over b in group g of A_ab Q_b, so the
    /// group correction's product reads a few blocks per node: node a's at
    /// coupling_first[a] .. [a + 1], their groups in coupling_group.
    std::vector<std::size_t> coupling_first;
    std::vector<int> coupling_group;
    std::vector<std::size_t> coupling_of_slot;  ///< each slot (a, b): K_ag's index, g b's group
    std::vector<ModeMatrix> coupling;
    /// solve(): per node in its modes, the right-hand side, the solution, and the residual
    /// after the first smoothing.
    std::vector<Modes> rhs, solution, residual;
    /// solve_groups(): the first cycle's right-hand side and solution.
    std::vector<Modes> first_rhs, first_solution;
    [[nodiscard]] std::size_t size() const { return diagonal_slot.size(); }
  };
  /// Adds the level above level `below`: its `groups` groups, each node's in `group_of`; and
  /// level `below`'s patterns that depend on them (mirrors, couplings).
  void add_group_level(std::size_t below, std::vector<int> group_of, std::size_t groups);
  /// Level k's groups' centres and modes, and its nodes' maps to them.
  void shape_groups(std::size_t k, std::span<const Vec3> centre,
                    std::span<const ModeMatrix> modes_from_raw);
  /// Level k's single blocks, own inverses (damped) and couplings; then level k + 1's blocks.
  void prepare_smoother(std::size_t k);
  /// The top level's scalar pattern (from its slots).
  void build_exact();
  /// Level k's node a: c - (A y)_a with the quantized blocks.
  [[nodiscard]] static Modes residual_of(const Level& level, std::size_t a, const Modes& c,
                                         const std::vector<Modes>& y);
  /// The largest eigenvalue of (own blocks' inverses) A on level k, by power iteration.
  [[nodiscard]] double smoother_reach(std::size_t k) const;
  /// Level k's solution for its rhs by one V-cycle (the top: exact).
  void cycle(std::size_t k);
  /// A level of groups' solution for its rhs: two V-cycles (a W-cycle, where one V-cycle
  /// left CG 79 iterations on the 384k-tet box and two 75, for little: the groups are an
  /// eighth of the aggregates), or the top's exact solve.
  void solve_groups(std::size_t k);

  std::vector<Level> levels_;
  /// The top level's matrix as scalars: nonzero -> (slot, entry in the 6x6 block).
  std::vector<std::pair<int, int>> scalar_source_;
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> scalar_;
  Eigen::VectorXd top_rhs_;
  std::unique_ptr<DirectFactorization> factor_;
};

}  // namespace coarse
}  // namespace incise
