#pragma once
// Solvers for the linearised systems of implicit steps and static equilibrium:
//   (mass_scale M + a K + b D) x = rhs   on the vertices that are not constrained,
// by preconditioned conjugate gradients (products from the system, matrix-free or assembled)
// or by a sparse direct factorisation of the assembled matrix (CHOLMOD's supernodal Cholesky
// where built with it, else Eigen's SimplicialLDLT; see direct_factorization.hpp). Every
// reduction is summed in fixed chunks, so results do not depend on the thread count.

#include <Eigen/SparseCore>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/core/timing.hpp"
#include "incise/physics/block_sparse.hpp"
#include "incise/physics/dynamic_system.hpp"

namespace incise {

class AggregationCoarseSpace;
class ClusterJacobi;
class DirectFactorization;

/// kAuto: the direct factorisation up to auto_direct_limit() free unknowns, CG above (measured
/// in BENCHMARKS.md: factorised Newton steps converge where block-Jacobi CG stalls on slender
/// bodies; CG's memory grows slower on very large ones).
enum class LinearSolverType { kConjugateGradient, kDirect, kAuto };
/// kTwoLevel: block-Jacobi plus an aggregation coarse level (see aggregation_coarse_space.hpp);
/// needs a model that assembles its matrix.
enum class Preconditioner { kNone, kJacobi, kBlockJacobi, kIncompleteCholesky, kTwoLevel };

/// Free scalar unknowns up to which kAuto factorises: 150,000 with CHOLMOD (about 1 GB of
/// factor at most), 15,000 with the simplicial fallback.
[[nodiscard]] std::size_t auto_direct_limit();

/// How implicit steps solve their linear systems (scene key `integrator.solver`).
struct LinearSolverOptions {
  LinearSolverType type = LinearSolverType::kConjugateGradient;  ///< cg, direct or auto
  Preconditioner preconditioner = Preconditioner::kBlockJacobi;  ///< CG's
  double tolerance = 1e-8;                                       ///< relative residual |r| / |rhs|
  int max_iterations = 500;  ///< CG iterations at most per solve
  /// Start CG from the caller's x (the last solution) instead of zero.
  bool warm_start = true;
  /// Implicit integrators keep this many earlier solutions and start CG from their best
  /// combination (Galerkin projection); 0 extrapolates the last two linearly instead.
  int start_history = 8;
  /// Run CG on the assembled matrix when the system can assemble it (fused passes); false
  /// multiplies through the system's matrix-free products (kept for comparison).
  bool assembled = true;
  /// Assembled CG multiplies by a single-precision copy of the matrix (half the bytes per
  /// product), stopping on the residual formed in double: see fused_conjugate_gradients.
  bool single_precision_products = true;
};

/// Parses "cg" / "direct" / "auto" and "none" / "jacobi" / "block-jacobi" / "incomplete-cholesky"
/// / "two-level";
/// throws InputError listing the valid names.
[[nodiscard]] LinearSolverType parse_linear_solver_type(const std::string& name);
[[nodiscard]] Preconditioner parse_preconditioner(const std::string& name);
[[nodiscard]] std::string to_string(Preconditioner preconditioner);

/// What one linear solve did.
struct LinearSolveStats {
  int iterations = 0;              ///< CG iterations (1 for a direct solve)
  double relative_residual = 0.0;  ///< |r| / |rhs| reached
  /// Restarts of CG on the residual formed in double after a run in single precision ended
  /// above the tolerance (iterative refinement).
  int refinements = 0;
  double seconds_preconditioner = 0.0;  ///< building it (factorisation for direct solves)
  double seconds_products = 0.0;        ///< matrix-vector products
  double seconds_vector_updates = 0.0;  ///< the x, r, z updates and their dot products
  double seconds_start = 0.0;           ///< the starting guess from a basis
  double seconds_total = 0.0;           ///< the whole solve
  bool direct = false;  ///< solved by factorisation (kDirect, or kAuto below its limit)
};

/// Solves an implicit step's linear system (M + a D + b K) x = rhs of a DynamicSystem by
/// preconditioned CG or a direct factorisation, keeping what the next solves can reuse.
class LinearizedSystemSolver {
 public:
  /// Solves as `options` say.
  explicit LinearizedSystemSolver(const LinearSolverOptions& options = {});
  ~LinearizedSystemSolver();
  LinearizedSystemSolver(const LinearizedSystemSolver&) = delete;
  LinearizedSystemSolver& operator=(const LinearizedSystemSolver&) = delete;

  /// Solves for x after system.prepare_linearization(). Rows of constrained vertices (nonzero
  /// in `constrained`) are identity with x = 0 there. x holds the warm start on entry.
  /// Throws InputError if a direct solve or incomplete Cholesky is asked of a system that
  /// cannot assemble its matrix, or if the factorisation fails.
  /// `start_basis`, when given, replaces the warm start: CG starts from the combination of
  /// these fields that minimises the error in the energy norm over their span (they are
  /// typically the solutions of earlier steps; dependent ones are harmless).
  LinearSolveStats solve(const DynamicSystem& system, double mass_scale, double a, double b,
                         std::span<const char> constrained, std::span<const Vec3> rhs,
                         std::span<Vec3> x,
                         std::span<const std::span<const Vec3>> start_basis = {});
  [[nodiscard]] const LinearSolverOptions& options() const { return options_; }  ///< as given
  /// Where the next solve's system is linearised (m, one per vertex; empty: unknown): the
  /// two-level preconditioner's coarse modes rotate about these positions, else translate
  /// only. Read by the next solve() only, so the span must stay valid until then.
  void set_linearization_positions(std::span<const Vec3> positions) { positions_ = positions; }
  /// What the next solves depend on beyond their arguments (a checkpoint): the two-level
  /// preconditioner's clusters and coarse level, which follow the steps and cuts.
  void save_state(StateWriter& out) const;
  void load_state(StateReader& in);  ///< restores what save_state() wrote

 private:
  using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  void apply(const DynamicSystem& system, double mass_scale, double a, double b,
             std::span<const Vec3> p, std::span<Vec3> y);
  bool assemble(const DynamicSystem& system, double mass_scale, double a, double b);
  /// The (block-)Jacobi preconditioner's block for a diagonal block of the system matrix
  /// (identity without preconditioning).
  [[nodiscard]] Mat3 preconditioner_block(const Mat3& diagonal_block) const;
  /// PCG over the assembled matrix with fused passes (Jacobi, block-Jacobi, two-level or none),
  /// from x when start_from_x, else from zero. With single-precision products, each run starts
  /// from the residual formed in double and CG restarts from it until that meets the tolerance
  /// (iterative refinement; double products if a restart fails to halve it).
  /// `start_product`, when given, is A x for the starting x (from the Galerkin start), so the
  /// first residual needs no product.
  void fused_conjugate_gradients(std::span<const Vec3> rhs, std::span<Vec3> x, double rhs_norm,
                                 bool start_from_x, LinearSolveStats& stats,
                                 std::span<const Vec3> start_product = {});
  /// After the assembled matrix and its preconditioner are built: the start (the Galerkin one
  /// from start_basis when given), then the fused PCG; stats' total time counts from `start`.
  LinearSolveStats fused_solve(std::span<const Vec3> rhs, std::span<Vec3> x, double rhs_norm,
                               std::span<const std::span<const Vec3>> start_basis,
                               Clock::time_point start, LinearSolveStats& stats);
  /// Whether CG starts from the caller's x: a warm start or a basis start was asked for and
  /// x is nonzero on some free row.
  [[nodiscard]] bool starts_from_x(std::span<const Vec3> x, bool basis_given) const;
  /// x = the Galerkin combination of `basis` (see solve()); `product(p, y)` applies the
  /// matrix to every vector of p at once. Its time goes to stats.seconds_start. When
  /// `start_product` is not empty, it receives A x, combined from the basis' products.
  template <typename Product>
  void galerkin_start(std::span<const std::span<const Vec3>> basis, std::span<const Vec3> rhs,
                      std::span<Vec3> x, const Product& product, LinearSolveStats& stats,
                      std::span<Vec3> start_product = {});
  void build_scalar_pattern();
  void fill_scalar_values();

  LinearSolverOptions options_;
  std::span<const double> masses_;
  std::span<const char> constrained_;
  std::span<const Vec3> positions_;
  std::vector<Vec3> residual_, direction_, product_, preconditioned_;
  std::vector<Vec3> start_product_;  ///< A x for the Galerkin start x
  std::vector<Mat3> diagonal_;
  std::vector<std::vector<Vec3>> basis_products_;
  std::vector<std::vector<Vec3>> masked_basis_;
  BlockSparseMatrix assembled_;
  // Scalar copy of the free rows and columns for LDL^T and incomplete Cholesky.
  /// The block pattern the scalar one was built from (held, so its address is not reused).
  std::shared_ptr<const BlockPattern> scalar_pattern_;
  std::uint64_t scalar_pattern_version_ = 0;
  std::vector<char> scalar_constrained_;
  std::vector<int> free_index_;             ///< vertex -> first scalar unknown, or -1
  std::vector<std::size_t> scalar_source_;  ///< scalar nonzero -> offset in the block values
  SparseMatrix scalar_;
  std::unique_ptr<DirectFactorization> direct_;
  struct IncompleteCholesky;
  std::unique_ptr<IncompleteCholesky> incomplete_;
  std::unique_ptr<AggregationCoarseSpace> coarse_;
  std::unique_ptr<ClusterJacobi> clusters_;
  Eigen::VectorXd scalar_rhs_, scalar_solution_;
};

/// Whether direct solves use CHOLMOD's supernodal Cholesky (built with INCISE_WITH_CHOLMOD).
[[nodiscard]] bool has_cholmod_backend();

/// Deterministic parallel dot product of two vertex fields (fixed chunks, summed in order).
[[nodiscard]] double parallel_dot(std::span<const Vec3> a, std::span<const Vec3> b);

}  // namespace incise
