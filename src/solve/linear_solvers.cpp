#include "incise/solve/linear_solvers.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/IterativeLinearSolvers>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/core/timing.hpp"
#include "incise/solve/aggregation_coarse_space.hpp"
#include "incise/solve/cluster_jacobi.hpp"
#include "incise/solve/direct_factorization.hpp"

namespace incise {

namespace {

/// Reductions are summed over chunks of this many vertices, then the chunks in order.
constexpr std::size_t kChunk = 2048;
/// Rows per chunk of the fused CG passes (reductions in the same fixed order); the coarse
/// restriction's chunks, which the update pass sums.
constexpr std::size_t kFusedChunk = 1024;
static_assert(kFusedChunk == AggregationCoarseSpace::kRestrictionChunk);
/// The tightest tolerance at which the Galerkin start multiplies in single precision: its
/// start is then within float's rounding, 1e-7 of the solution, a hundredth of the tolerance.
/// Tighter, a float start would cost CG iterations to undo (0.3 ms a step on the 50k-tet body).
constexpr double kSingleStartTolerance = 1e-5;

template <typename Body>
void parallel_vertices(std::size_t n, const Body& body) {
  parallel_for(0, n, kChunk, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      body(i);
    }
  });
}

/// `count` sums over i < n at once, deterministic: body(begin, end, sums) sets sums[0..count)
/// to the sums over rows begin <= i < end (accumulating in locals: neighbouring chunks'
/// entries share cache lines across threads); each fixed chunk of `chunk` rows is summed by one
/// thread, then the chunks in order, so the result does not depend on the thread count.
template <typename Body>
std::vector<double> chunked_sums(std::size_t n, std::size_t chunk, std::size_t count,
                                 const Body& body) {
  const std::size_t chunks = (n + chunk - 1) / chunk;
  std::vector<double> partial(chunks * count, 0.0);
  parallel_for(0, chunks, 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t c = first; c != last; ++c) {
      body(c * chunk, std::min(n, (c + 1) * chunk), &partial[c * count]);
    }
  });
  std::vector<double> total(count, 0.0);
  for (std::size_t c = 0; c < chunks; ++c) {
    for (std::size_t m = 0; m < count; ++m) {
      total[m] += partial[c * count + m];
    }
  }
  return total;
}

/// Two sums at once (see above): body(begin, end, first, second).
template <typename Body>
std::pair<double, double> chunked_sums(std::size_t n, std::size_t chunk, const Body& body) {
  const std::vector<double> sums =
      chunked_sums(n, chunk, 2, [&](std::size_t begin, std::size_t end, double* out) {
        double first = 0.0;
        double second = 0.0;
        body(begin, end, first, second);
        out[0] = first;
        out[1] = second;
      });
  return {sums[0], sums[1]};
}

/// sum_i term(i), deterministic (see chunked_sums).
template <typename Term>
double parallel_sum(std::size_t n, const Term& term) {
  return chunked_sums(n, kChunk,
                      [&](std::size_t begin, std::size_t end, double& sum, double&) {
                        for (std::size_t i = begin; i < end; ++i) {
                          sum += term(i);
                        }
                      })
      .first;
}

}  // namespace

double parallel_dot(std::span<const Vec3> a, std::span<const Vec3> b) {
  return parallel_sum(a.size(), [&](std::size_t i) { return a[i].dot(b[i]); });
}

LinearSolverType parse_linear_solver_type(const std::string& name) {
  if (name == "cg") {
    return LinearSolverType::kConjugateGradient;
  }
  if (name == "direct") {
    return LinearSolverType::kDirect;
  }
  if (name == "auto") {
    return LinearSolverType::kAuto;
  }
  throw InputError("unknown linear solver '" + name + "' (known: cg, direct, auto)");
}

Preconditioner parse_preconditioner(const std::string& name) {
  if (name == "none") {
    return Preconditioner::kNone;
  }
  if (name == "jacobi") {
    return Preconditioner::kJacobi;
  }
  if (name == "block-jacobi") {
    return Preconditioner::kBlockJacobi;
  }
  if (name == "incomplete-cholesky") {
    return Preconditioner::kIncompleteCholesky;
  }
  if (name == "two-level") {
    return Preconditioner::kTwoLevel;
  }
  throw InputError("unknown preconditioner '" + name +
                   "' (known: none, jacobi, block-jacobi, incomplete-cholesky, two-level)");
}

std::string to_string(Preconditioner preconditioner) {
  switch (preconditioner) {
    case Preconditioner::kNone:
      return "none";
    case Preconditioner::kJacobi:
      return "jacobi";
    case Preconditioner::kBlockJacobi:
      return "block-jacobi";
    case Preconditioner::kIncompleteCholesky:
      return "incomplete-cholesky";
    case Preconditioner::kTwoLevel:
      return "two-level";
  }
  return "?";
}

struct LinearizedSystemSolver::IncompleteCholesky {
  Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<int>> factor;
};

LinearizedSystemSolver::LinearizedSystemSolver(const LinearSolverOptions& options)
    : options_(options) {
  if (!(options_.tolerance > 0.0) || options_.max_iterations < 1) {
    throw InputError("linear solver tolerance must be positive and iterations at least 1");
  }
}

LinearizedSystemSolver::~LinearizedSystemSolver() = default;

void LinearizedSystemSolver::apply(const DynamicSystem& system, double mass_scale, double a,
                                   double b, std::span<const Vec3> p, std::span<Vec3> y) {
  parallel_vertices(p.size(), [&](std::size_t i) { y[i] = mass_scale * masses_[i] * p[i]; });
  system.add_linearized_product(a, b, p, y);
  parallel_vertices(p.size(), [&](std::size_t i) {
    if (constrained_[i] != 0) {
      y[i] = p[i];  // identity rows keep the operator positive definite
    }
  });
}

bool LinearizedSystemSolver::assemble(const DynamicSystem& system, double mass_scale, double a,
                                      double b) {
  if (!system.assemble_linearization(a, b, assembled_)) {
    return false;
  }
  // Each row's own block, on the workers (serial, 2 ms a step at 384k tets).
  auto values = assembled_.values();
  parallel_vertices(assembled_.rows(), [&](std::size_t i) {
    values[assembled_.diagonal(static_cast<VertexId>(i))] +=
        mass_scale * masses_[i] * Mat3::Identity();
  });
  return true;
}

void LinearizedSystemSolver::build_scalar_pattern() {
  const std::size_t n = assembled_.rows();
  free_index_.assign(n, -1);
  int unknowns = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained_[i] == 0) {
      free_index_[i] = unknowns;
      unknowns += 3;
    }
  }
  // Columns of the scalar matrix are the block rows' entries (the matrix is symmetric), so
  // column-major storage is filled row by row of blocks.
  const auto row_begin = assembled_.row_begin();
  const auto row_end = assembled_.row_end();
  const auto columns = assembled_.columns();
  std::vector<int> outer(static_cast<std::size_t>(unknowns) + 1, 0);
  std::vector<int> inner;
  scalar_source_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (free_index_[i] < 0) {
      continue;
    }
    for (int component = 0; component < 3; ++component) {
      const int column = free_index_[i] + component;
      for (std::size_t k = row_begin[i]; k < row_end[i]; ++k) {
        const int other = free_index_[columns[k]];
        if (other < 0) {
          continue;
        }
        for (int r = 0; r < 3; ++r) {
          inner.push_back(other + r);
          // Block (i, j) stored column-major: entry (component, r) of block (j, i) is
          // entry (r, component) of block (i, j)'s transpose; both hold the same value.
          scalar_source_.push_back(9 * k + static_cast<std::size_t>(3 * r + component));
        }
      }
      outer[static_cast<std::size_t>(column) + 1] = static_cast<int>(inner.size());
    }
  }
  scalar_.resize(unknowns, unknowns);
  scalar_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), scalar_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), scalar_.innerIndexPtr());
  scalar_pattern_ = assembled_.pattern();
  scalar_pattern_version_ = assembled_.pattern_version();
  scalar_constrained_.assign(constrained_.begin(), constrained_.end());
}

void LinearizedSystemSolver::fill_scalar_values() {
  if (scalar_pattern_ != assembled_.pattern() ||
      scalar_pattern_version_ != assembled_.pattern_version() ||
      scalar_constrained_.size() != constrained_.size() ||
      !std::equal(constrained_.begin(), constrained_.end(), scalar_constrained_.begin())) {
    build_scalar_pattern();
  }
  const double* source = assembled_.values().data()->data();
  double* target = scalar_.valuePtr();
  // Block (i, j) column-major: value (r, c) at offset 3 c + r. Column `component` of the
  // scalar matrix inside block row i holds A(i_r, i_component)... symmetric, so read (r, c)
  // of block (i, j) as (c, r) of block (j, i): offsets were stored to match.
  parallel_for(0, scalar_source_.size(), 1 << 14, [&](std::size_t first, std::size_t last) {
    for (std::size_t s = first; s != last; ++s) {
      target[s] = source[scalar_source_[s]];
    }
  });
}

Mat3 LinearizedSystemSolver::preconditioner_block(const Mat3& diagonal_block) const {
  switch (options_.preconditioner) {
    case Preconditioner::kBlockJacobi:
    case Preconditioner::kTwoLevel:
      return diagonal_block.inverse();
    case Preconditioner::kJacobi:
      return diagonal_block.diagonal().cwiseInverse().asDiagonal();
    default:
      return Mat3::Identity();
  }
}

void LinearizedSystemSolver::fused_conjugate_gradients(std::span<const Vec3> rhs, std::span<Vec3> x,
                                                       double rhs_norm, bool start_from_x,
                                                       LinearSolveStats& stats,
                                                       std::span<const Vec3> start_product) {
  // Two passes over memory per iteration: the new direction p and q = J p with p.q; the x, r
  // and z updates with r.r and r.z. Held rows are identity with r = z = p = 0 there.
  const std::size_t n = rhs.size();
  const auto values = assembled_.values();
  resize_for_edits(residual_, n);
  resize_for_edits(direction_, n);
  resize_for_edits(product_, n);
  resize_for_edits(preconditioned_, n);
  resize_for_edits(diagonal_, n);
  const bool two_level = options_.preconditioner == Preconditioner::kTwoLevel;
  // Products in single precision read half the bytes; the initial residual of each pass below
  // is formed in double, so CG stops on the true residual: when the single-precision run ends
  // above the tolerance, it restarts from there on the true residual (iterative refinement),
  // and falls back to double products if a restart does not halve it.
  bool single = options_.single_precision_products;  // the copy is fresh: see fused_solve
  auto multiply = [&](bool in_single, std::size_t begin, std::size_t end, std::span<const Vec3> p,
                      Vec3* out) {
    if (in_single) {
      assembled_.multiply_rows_single(begin, end, p, out);
    } else {
      assembled_.multiply_rows(begin, end, p, out);
    }
  };
  // Each pass walks fixed chunks of rows; a chunk's matrix rows are multiplied into `rows`
  // first (the kernel), then combined with the vectors row by row.
  auto chunked = [&](const auto& row_body) {
    return chunked_sums(n, kFusedChunk,
                        [&](std::size_t begin, std::size_t end, double& first, double& second) {
                          for (std::size_t i = begin; i < end; ++i) {
                            row_body(i, first, second);
                          }
                        });
  };
  auto chunked_products = [&](bool in_single, std::span<const Vec3> p, const auto& row_body) {
    return chunked_sums(n, kFusedChunk,
                        [&](std::size_t begin, std::size_t end, double& first, double& second) {
                          std::array<Vec3, kFusedChunk> rows;
                          multiply(in_single, begin, end, p, rows.data());
                          for (std::size_t i = begin; i < end; ++i) {
                            row_body(i, rows[i - begin], first, second);
                          }
                        });
  };
  // The two-level preconditioner's per-row part (vertices alone in their cluster) runs in the
  // passes below; once the whole residual is known, the clusters' blocks and the
  // coarse correction add theirs, and their part of r.z (the coarse one is
  // (P^T r).(A_c^-1 P^T r), so it needs no pass of its own).
  auto precondition_two_level = [&](bool set_direction, bool restricted) {
    // The clusters and the coarse solve read r and write apart (z on clustered rows; the
    // coarse solution), so they run at once: the coarse solve's factorised solve is
    // sequential and would otherwise leave the other cores idle (its passes run on the workers
    // that the clusters leave free).
    double cluster_sum = 0.0;
    double coarse_sum = 0.0;
    parallel_invoke(
        [&] { cluster_sum = clusters_->apply_clusters(residual_, preconditioned_); },
        [&] { coarse_sum = restricted ? coarse_->solve_restricted() : coarse_->solve(residual_); });
    const double sum = cluster_sum + coarse_sum;
    coarse_->add_correction(preconditioned_);
    if (set_direction) {
      std::copy(preconditioned_.begin(), preconditioned_.end(), direction_.begin());
    }
    return sum;
  };
  if (!start_from_x) {
    std::fill(x.begin(), x.end(), Vec3::Zero());
  }
  int iteration = 0;
  double last_true_residual = std::numeric_limits<double>::infinity();
  // The first residual from the start's own product: with single-precision products it is
  // within rounding of float of the true one, so a stop on it is confirmed in double first.
  bool from_start_product = start_from_x && !start_product.empty();
  for (;;) {
    // Preconditioner and the initial residual (warm start from x).
    const auto first_pass = [&](std::size_t i, const Vec3& row_x, double& sum_rr, double& sum_rz) {
      if (constrained_[i] != 0) {
        diagonal_[i].setZero();
        residual_[i].setZero();
        preconditioned_[i].setZero();
        direction_[i].setZero();
        product_[i].setZero();  // never written again: held rows stay out of every update
        return;
      }
      diagonal_[i] =
          two_level ? clusters_->single_inverse()[i]
                    : preconditioner_block(values[assembled_.diagonal(static_cast<VertexId>(i))]);
      residual_[i] = rhs[i] - row_x;  // x is zero on a cold start
      preconditioned_[i].noalias() = diagonal_[i] * residual_[i];
      direction_[i] = preconditioned_[i];
      sum_rr += residual_[i].squaredNorm();
      sum_rz += residual_[i].dot(preconditioned_[i]);
    };
    const bool estimated = from_start_product && single;
    auto [rr, rz] = from_start_product
                        ? chunked([&](std::size_t i, double& sum_rr, double& sum_rz) {
                            first_pass(i, start_product[i], sum_rr, sum_rz);
                          })
                        : chunked_products(false, x, first_pass);
    from_start_product = false;
    if (two_level) {
      rz += precondition_two_level(true, false);
    }
    // The true residual (double products), or on the first pass its estimate.
    stats.relative_residual = std::sqrt(rr) / rhs_norm;
    if (estimated) {
      if (!(stats.relative_residual > options_.tolerance)) {
        continue;  // converged on the estimate: confirmed on the true residual
      }
    } else {
      if (single && stats.relative_residual > options_.tolerance &&
          !(stats.relative_residual < 0.5 * last_true_residual)) {
        single = false;  // refinement stalled: the single-precision matrix is too far off
      }
      last_true_residual = stats.relative_residual;
    }
    // Done when converged, out of iterations, or not a number (a matrix or start holding NaN:
    // the caller's divergence check reports it; CG would only restart on it forever).
    if (!(stats.relative_residual > options_.tolerance) || iteration >= options_.max_iterations) {
      break;
    }
    if (iteration > 0) {
      ++stats.refinements;
    }
    bool broke_down = false;
    // q = J p for the first direction; afterwards J p_new = J z + beta J p_old is formed in the
    // same pass as J z, so an iteration is two passes (the p and q recurrences are exact
    // identities; only rounding differs from forming J p directly).
    double beta = 0.0;
    bool first_direction = true;
    while (stats.relative_residual > options_.tolerance && iteration < options_.max_iterations) {
      const auto product_start = Clock::now();
      const double curvature =
          chunked_products(single,
                           first_direction ? std::span<const Vec3>(direction_)
                                           : std::span<const Vec3>(preconditioned_),
                           [&](std::size_t i, const Vec3& row_p, double& sum, double&) {
                             if (constrained_[i] != 0) {
                               return;
                             }
                             if (first_direction) {
                               product_[i] = row_p;
                             } else {
                               direction_[i] = preconditioned_[i] + beta * direction_[i];
                               product_[i] = row_p + beta * product_[i];
                             }
                             sum += direction_[i].dot(product_[i]);
                           })
              .first;
      stats.seconds_products += seconds_since(product_start);
      if (!(curvature > 0.0)) {
        broke_down = true;  // converged to rounding, or not positive definite: keep x
        break;
      }
      const double alpha = rz / curvature;
      const auto update_start = Clock::now();
      // With two levels, each chunk's part of the coarse restriction P^T r is summed here,
      // while the chunk's new residual is in cache (a pass of its own read it all again).
      auto [rr_next, rz_next] = chunked_sums(
          n, kFusedChunk, [&](std::size_t begin, std::size_t end, double& sum_rr, double& sum_rz) {
            for (std::size_t i = begin; i < end; ++i) {
              x[i] += alpha * direction_[i];
              residual_[i] -= alpha * product_[i];
              preconditioned_[i].noalias() = diagonal_[i] * residual_[i];
              sum_rr += residual_[i].squaredNorm();
              sum_rz += residual_[i].dot(preconditioned_[i]);
            }
            if (two_level) {
              coarse_->restrict_chunk(begin / kFusedChunk, residual_);
            }
          });
      if (two_level && std::sqrt(rr_next) / rhs_norm > options_.tolerance) {
        rz_next += precondition_two_level(false, true);
      }
      stats.seconds_vector_updates += seconds_since(update_start);
      ++iteration;
      first_direction = false;
      stats.relative_residual = std::sqrt(rr_next) / rhs_norm;
      beta = rz_next / rz;
      rz = rz_next;
    }
    if (!single || broke_down) {
      break;  // in double the recurrence's residual is the answer, as it always was
    }
  }
  stats.iterations = iteration;
}

void LinearizedSystemSolver::save_state(StateWriter& out) const {
  out.tag("linear solver");
  out.value(coarse_ != nullptr);
  if (coarse_) {
    clusters_->save_state(out);
    coarse_->save_state(out);
  }
}

void LinearizedSystemSolver::load_state(StateReader& in) {
  in.tag("linear solver");
  if (!in.value<bool>("two-level preconditioner present")) {
    coarse_.reset();
    clusters_.reset();
    return;
  }
  if (options_.preconditioner != Preconditioner::kTwoLevel ||
      options_.type == LinearSolverType::kDirect) {
    throw InputError(
        "checkpoint: it holds a two-level preconditioner, but the scene's solver has none");
  }
  auto clusters = std::make_unique<ClusterJacobi>();
  auto coarse = std::make_unique<AggregationCoarseSpace>();
  clusters->load_state(in);
  coarse->load_state(in);
  clusters_ = std::move(clusters);
  coarse_ = std::move(coarse);
}

bool LinearizedSystemSolver::starts_from_x(std::span<const Vec3> x, bool basis_given) const {
  if (!options_.warm_start && !basis_given) {
    return false;
  }
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (constrained_[i] == 0 && !x[i].isZero(0.0)) {
      return true;
    }
  }
  return false;  // all zero: the cold start saves the product of x
}

template <typename Product>
void LinearizedSystemSolver::galerkin_start(std::span<const std::span<const Vec3>> basis,
                                            std::span<const Vec3> rhs, std::span<Vec3> x,
                                            const Product& product, LinearSolveStats& stats,
                                            std::span<Vec3> start_product) {
  const auto began = Clock::now();
  // x = V y with (V^T A V) y = V^T rhs: the best start in span(V) in the energy norm, so never
  // worse than any one basis field or the linear extrapolation of two. The small system is
  // solved by its eigenvectors, dropping directions the basis does not span (earlier
  // solutions can be nearly parallel).
  const std::size_t k = basis.size();
  const std::size_t n = rhs.size();
  // Held rows are zero in x, so they are dropped from the basis before multiplying. Earlier
  // solutions are zero there already unless the held rows changed since: only then is the
  // basis copied with them zeroed (the copy of every field cost 1.5-1.8 ms a step at 384k
  // tets).
  const auto held_and_nonzero = [&](std::size_t i) {
    double count = 0.0;
    if (constrained_[i] != 0) {
      for (std::size_t j = 0; j < k; ++j) {
        count += basis[j][i].isZero(0.0) ? 0.0 : 1.0;
      }
    }
    return count;
  };
  const bool held_rows_zero = parallel_sum(n, held_and_nonzero) == 0.0;
  std::vector<std::span<const Vec3>> masked(k);
  if (held_rows_zero) {
    for (std::size_t j = 0; j < k; ++j) {
      masked[j] = basis[j].first(n);
    }
  } else {
    masked_basis_.resize(k);
    for (std::size_t j = 0; j < k; ++j) {
      resize_for_edits(masked_basis_[j], n);
      masked[j] = masked_basis_[j];
    }
    parallel_vertices(n, [&](std::size_t i) {
      for (std::size_t j = 0; j < k; ++j) {
        masked_basis_[j][i] = constrained_[i] != 0 ? Vec3::Zero() : basis[j][i];
      }
    });
  }
  basis_products_.resize(k);
  std::vector<std::span<Vec3>> products(k);
  for (std::size_t j = 0; j < k; ++j) {
    resize_for_edits(basis_products_[j], n);
    products[j] = basis_products_[j];
  }
  product(std::span<const std::span<const Vec3>>(masked),
          std::span<const std::span<Vec3>>(products));
  // V^T A V (lower triangle, row by row) and V^T rhs over the free rows, in one pass.
  const std::size_t pairs = k * (k + 1) / 2;
  const std::vector<double> sums =
      chunked_sums(n, kChunk, pairs + k, [&](std::size_t begin, std::size_t end, double* out) {
        std::vector<double> local(pairs + k, 0.0);
        for (std::size_t i = begin; i < end; ++i) {
          if (constrained_[i] != 0) {
            continue;
          }
          std::size_t entry = 0;
          for (std::size_t row = 0; row < k; ++row) {
            for (std::size_t column = 0; column <= row; ++column) {
              local[entry++] += basis[row][i].dot(basis_products_[column][i]);
            }
          }
          for (std::size_t row = 0; row < k; ++row) {
            local[pairs + row] += basis[row][i].dot(rhs[i]);
          }
        }
        std::copy(local.begin(), local.end(), out);
      });
  Eigen::MatrixXd gram(k, k);
  Eigen::VectorXd load(k);
  std::size_t entry = 0;
  for (std::size_t row = 0; row < k; ++row) {
    for (std::size_t column = 0; column <= row; ++column) {
      const auto r = static_cast<Eigen::Index>(row);
      const auto c = static_cast<Eigen::Index>(column);
      gram(r, c) = sums[entry];
      gram(c, r) = sums[entry];
      ++entry;
    }
    load(static_cast<Eigen::Index>(row)) = sums[pairs + row];
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram);
  const Eigen::VectorXd& values = eigen.eigenvalues();
  Eigen::VectorXd combination = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(k));
  const double largest = values.size() > 0 ? values.maxCoeff() : 0.0;
  for (Eigen::Index m = 0; m < values.size(); ++m) {
    if (largest > 0.0 && values(m) > 1e-12 * largest) {
      const Eigen::VectorXd direction = eigen.eigenvectors().col(m);
      combination += (direction.dot(load) / values(m)) * direction;
    }
  }
  const bool with_product = !start_product.empty();
  parallel_vertices(n, [&](std::size_t i) {
    Vec3 start = Vec3::Zero();
    Vec3 start_times_matrix = Vec3::Zero();
    if (constrained_[i] == 0) {
      for (std::size_t j = 0; j < k; ++j) {
        const double c = combination(static_cast<Eigen::Index>(j));
        start += c * basis[j][i];
        if (with_product) {
          start_times_matrix += c * basis_products_[j][i];
        }
      }
    }
    x[i] = start;
    if (with_product) {
      start_product[i] = start_times_matrix;
    }
  });
  stats.seconds_start += seconds_since(began);
}

LinearSolveStats LinearizedSystemSolver::fused_solve(
    std::span<const Vec3> rhs, std::span<Vec3> x, double rhs_norm,
    std::span<const std::span<const Vec3>> start_basis, Clock::time_point start,
    LinearSolveStats& stats) {
  if (options_.single_precision_products) {
    const auto refresh_start = Clock::now();
    assembled_.refresh_single_precision();
    stats.seconds_products += seconds_since(refresh_start);
  }
  std::span<const Vec3> start_product;
  if (!start_basis.empty()) {
    // A basis that spans the solution starts CG at it. Its products in single precision
    // where float's rounding (about 1e-7 of each product) is far below the tolerance, else
    // in double. A x is their combination, so CG's first residual needs no product.
    const bool single_start =
        options_.single_precision_products && options_.tolerance >= kSingleStartTolerance;
    resize_for_edits(start_product_, rhs.size());
    galerkin_start(
        start_basis, rhs, x,
        [&](std::span<const std::span<const Vec3>> p, std::span<const std::span<Vec3>> y) {
          if (single_start) {
            assembled_.multiply_several_single(p, y);
          } else {
            assembled_.multiply_several(p, y);
          }
        },
        stats, start_product_);
    start_product = start_product_;
  }
  fused_conjugate_gradients(rhs, x, rhs_norm, starts_from_x(x, !start_basis.empty()), stats,
                            start_product);
  stats.seconds_total = seconds_since(start);
  return stats;
}

LinearSolveStats LinearizedSystemSolver::solve(const DynamicSystem& system, double mass_scale,
                                               double a, double b,
                                               std::span<const char> constrained,
                                               std::span<const Vec3> rhs, std::span<Vec3> x,
                                               std::span<const std::span<const Vec3>> start_basis) {
  const auto start = Clock::now();
  const std::size_t n = rhs.size();
  // Read once: the caller's span is not kept past this solve.
  const std::span<const Vec3> positions = std::exchange(positions_, {});
  masses_ = system.masses();
  constrained_ = constrained;
  LinearSolveStats stats;
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained_[i] != 0) {
      x[i].setZero();
    }
  }
  const double rhs_norm = std::sqrt(parallel_sum(
      n, [&](std::size_t i) { return constrained_[i] != 0 ? 0.0 : rhs[i].squaredNorm(); }));
  if (!(rhs_norm > 0.0)) {
    std::fill(x.begin(), x.end(), Vec3::Zero());
    stats.seconds_total = seconds_since(start);
    return stats;
  }
  std::size_t free_unknowns = 0;
  for (std::size_t i = 0; i < n; ++i) {
    free_unknowns += constrained_[i] == 0 ? 3 : 0;
  }
  bool direct = options_.type == LinearSolverType::kDirect ||
                (options_.type == LinearSolverType::kAuto && free_unknowns <= auto_direct_limit());
  bool needs_matrix = direct || options_.preconditioner == Preconditioner::kIncompleteCholesky ||
                      options_.preconditioner == Preconditioner::kTwoLevel;
  bool assembled = false;
  const auto matrix_start = Clock::now();
  if (needs_matrix) {
    assembled = assemble(system, mass_scale, a, b);
    if (!assembled && options_.type == LinearSolverType::kAuto) {
      // A matrix-free model: auto falls back to CG.
      direct = false;
      needs_matrix = options_.preconditioner == Preconditioner::kIncompleteCholesky ||
                     options_.preconditioner == Preconditioner::kTwoLevel;
    }
  }
  stats.direct = direct;
  if (needs_matrix) {
    if (!assembled) {
      throw InputError(
          "this model offers matrix-free products only: use the cg solver with the jacobi or "
          "block-jacobi preconditioner");
    }
  }
  if (needs_matrix && !direct && options_.preconditioner == Preconditioner::kTwoLevel) {
    if (!coarse_) {
      coarse_ = std::make_unique<AggregationCoarseSpace>();
      clusters_ = std::make_unique<ClusterJacobi>();
    }
    if (!clusters_->update(assembled_, constrained_)) {
      throw InputError(
          "the two-level preconditioner found a vertex block that is not positive definite "
          "(is every free vertex given a mass?)");
    }
    if (!coarse_->update(assembled_, constrained_,
                         positions.size() == n ? positions : std::span<const Vec3>{})) {
      throw InputError(
          "the two-level preconditioner could not factorise its coarse matrix (is the system "
          "positive definite?)");
    }
    stats.seconds_preconditioner = seconds_since(matrix_start);
    return fused_solve(rhs, x, rhs_norm, start_basis, start, stats);
  }
  if (needs_matrix) {
    fill_scalar_values();
    if (direct) {
      if (!direct_) {
        direct_ = std::make_unique<DirectFactorization>();
      }
      if (!direct_->factorize(scalar_)) {
        throw InputError(
            "the direct solver could not factorise the system matrix (is the body "
            "held, or does it have a mass?)");
      }
    } else {
      if (!incomplete_) {
        incomplete_ = std::make_unique<IncompleteCholesky>();
      }
      incomplete_->factor.compute(scalar_);
      if (incomplete_->factor.info() != Eigen::Success) {
        throw InputError("incomplete Cholesky factorisation failed");
      }
    }
    stats.seconds_preconditioner = seconds_since(matrix_start);
  }
  auto to_scalar = [&](std::span<const Vec3> field, Eigen::VectorXd& out) {
    out.resize(scalar_.rows());
    for (std::size_t i = 0; i < n; ++i) {
      if (free_index_[i] >= 0) {
        out.segment<3>(free_index_[i]) = field[i];
      }
    }
  };
  auto from_scalar = [&](const Eigen::VectorXd& in, std::span<Vec3> field) {
    for (std::size_t i = 0; i < n; ++i) {
      field[i] = free_index_[i] >= 0 ? Vec3(in.segment<3>(free_index_[i])) : Vec3::Zero();
    }
  };
  if (direct) {
    to_scalar(rhs, scalar_rhs_);
    scalar_solution_ = direct_->solve(scalar_rhs_);
    from_scalar(scalar_solution_, x);
    stats.iterations = 1;
    resize_for_edits(residual_, n);
    apply(system, mass_scale, a, b, x, residual_);
    stats.relative_residual =
        std::sqrt(parallel_sum(n,
                               [&](std::size_t i) {
                                 return constrained_[i] != 0
                                            ? 0.0
                                            : (rhs[i] - residual_[i]).squaredNorm();
                               })) /
        rhs_norm;
    stats.seconds_total = seconds_since(start);
    return stats;
  }

  if (options_.assembled && options_.preconditioner != Preconditioner::kIncompleteCholesky) {
    const auto build_start = Clock::now();
    if (assemble(system, mass_scale, a, b)) {
      stats.seconds_preconditioner += seconds_since(build_start);
      return fused_solve(rhs, x, rhs_norm, start_basis, start, stats);
    }
  }

  // Preconditioned conjugate gradients on the system's products (models that do not assemble).
  resize_for_edits(residual_, n);
  resize_for_edits(direction_, n);
  resize_for_edits(product_, n);
  resize_for_edits(preconditioned_, n);
  const auto build_start = Clock::now();
  if (options_.preconditioner == Preconditioner::kJacobi ||
      options_.preconditioner == Preconditioner::kBlockJacobi ||
      options_.preconditioner == Preconditioner::kTwoLevel) {
    resize_for_edits(diagonal_, n);
    parallel_vertices(
        n, [&](std::size_t i) { diagonal_[i] = mass_scale * masses_[i] * Mat3::Identity(); });
    system.add_linearized_diagonal(a, b, diagonal_);
    parallel_vertices(n, [&](std::size_t i) {
      diagonal_[i] =
          constrained_[i] != 0 ? Mat3(Mat3::Identity()) : preconditioner_block(diagonal_[i]);
    });
  }
  stats.seconds_preconditioner += seconds_since(build_start);
  auto precondition = [&](std::span<const Vec3> r, std::span<Vec3> z) {
    switch (options_.preconditioner) {
      case Preconditioner::kNone:
        std::copy(r.begin(), r.end(), z.begin());
        break;
      case Preconditioner::kJacobi:
      case Preconditioner::kBlockJacobi:
      case Preconditioner::kTwoLevel:  // solved on the assembled matrix above; never here
        parallel_vertices(n, [&](std::size_t i) { z[i].noalias() = diagonal_[i] * r[i]; });
        break;
      case Preconditioner::kIncompleteCholesky: {
        to_scalar(r, scalar_rhs_);
        scalar_solution_ = incomplete_->factor.solve(scalar_rhs_);
        from_scalar(scalar_solution_, z);
        break;
      }
    }
  };
  auto timed_apply = [&](std::span<const Vec3> p, std::span<Vec3> y) {
    const auto product_start = Clock::now();
    apply(system, mass_scale, a, b, p, y);
    stats.seconds_products += seconds_since(product_start);
  };
  if (!start_basis.empty()) {
    // Untimed products here: the start's products count in seconds_start.
    galerkin_start(
        start_basis, rhs, x,
        [&](std::span<const std::span<const Vec3>> p, std::span<const std::span<Vec3>> y) {
          for (std::size_t j = 0; j < p.size(); ++j) {
            apply(system, mass_scale, a, b, p[j], y[j]);
          }
        },
        stats);
  }
  if (starts_from_x(x, !start_basis.empty())) {
    timed_apply(x, product_);
    parallel_vertices(n, [&](std::size_t i) {
      residual_[i] = constrained_[i] != 0 ? Vec3::Zero() : Vec3(rhs[i] - product_[i]);
    });
  } else {
    std::fill(x.begin(), x.end(), Vec3::Zero());
    parallel_vertices(
        n, [&](std::size_t i) { residual_[i] = constrained_[i] != 0 ? Vec3::Zero() : rhs[i]; });
  }
  double residual_norm = std::sqrt(parallel_dot(residual_, residual_));
  stats.relative_residual = residual_norm / rhs_norm;
  if (stats.relative_residual <= options_.tolerance) {
    stats.seconds_total = seconds_since(start);
    return stats;
  }
  precondition(residual_, preconditioned_);
  std::copy(preconditioned_.begin(), preconditioned_.end(), direction_.begin());
  double rz = parallel_dot(residual_, preconditioned_);
  int iteration = 0;
  while (iteration < options_.max_iterations) {
    timed_apply(direction_, product_);
    const double curvature = parallel_dot(direction_, product_);
    if (!(curvature > 0.0)) {
      break;  // converged to rounding, or the matrix is not positive definite: keep x
    }
    const double alpha = rz / curvature;
    parallel_vertices(n, [&](std::size_t i) {
      x[i] += alpha * direction_[i];
      residual_[i] -= alpha * product_[i];
    });
    ++iteration;
    residual_norm = std::sqrt(parallel_dot(residual_, residual_));
    stats.relative_residual = residual_norm / rhs_norm;
    if (stats.relative_residual <= options_.tolerance) {
      break;
    }
    precondition(residual_, preconditioned_);
    const double rz_next = parallel_dot(residual_, preconditioned_);
    const double beta = rz_next / rz;
    rz = rz_next;
    parallel_vertices(
        n, [&](std::size_t i) { direction_[i] = preconditioned_[i] + beta * direction_[i]; });
  }
  stats.iterations = iteration;
  stats.seconds_total = seconds_since(start);
  return stats;
}

}  // namespace incise
