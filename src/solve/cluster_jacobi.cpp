#include "incise/solve/cluster_jacobi.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"

namespace incise {

namespace {

constexpr std::size_t kNoBlock = std::numeric_limits<std::size_t>::max();
/// Clusters per chunk of the r.z sum (fixed chunks summed in order: deterministic).
constexpr std::size_t kClusterChunk = 512;

}  // namespace

ClusterJacobi::ClusterJacobi(const ClusterOptions& options) : options_(options) {
  if (!(options_.threshold > 0.0) || options_.max_size < 1) {
    throw InputError("cluster threshold must be positive and clusters at least one vertex");
  }
}

VertexId ClusterJacobi::root(VertexId v) {
  while (parent_[static_cast<std::size_t>(v)] != v) {
    auto& up = parent_[static_cast<std::size_t>(v)];
    up = parent_[static_cast<std::size_t>(up)];
    v = up;
  }
  return v;
}

void ClusterJacobi::join_strong_pairs(const BlockSparseMatrix& matrix,
                                      std::span<const char> constrained,
                                      std::span<const char> regroup) {
  // Strong pairs with an end being regrouped, strongest first, ties by vertex ids
  // (deterministic); clusters merge while they stay within max_size.
  const std::size_t n = matrix.rows();
  const auto values = matrix.values();
  auto is_free = [&](std::size_t v) { return constrained[v] == 0; };
  auto diagonal_norm = [&](std::size_t v) {
    return values[matrix.diagonal(static_cast<VertexId>(v))].norm();
  };
  std::vector<std::tuple<double, VertexId, VertexId>> strong;
  for (std::size_t i = 0; i < n; ++i) {
    if (regroup[i] == 0 || !is_free(i)) {
      continue;
    }
    const auto row = matrix.row_columns(static_cast<VertexId>(i));
    const std::size_t first = matrix.row_begin()[i];
    const double di = diagonal_norm(i);
    for (std::size_t k = 0; k < row.size(); ++k) {
      // Each pair once: from its smaller vertex if both are regrouped, else from the one that is.
      const auto j = static_cast<std::size_t>(row[k]);
      if (!(j > i || regroup[j] == 0) || !is_free(j)) {
        continue;
      }
      const double scale = std::sqrt(di * diagonal_norm(j));
      const double strength = scale > 0.0 ? values[first + k].norm() / scale : 0.0;
      if (strength > options_.threshold) {
        strong.emplace_back(strength, static_cast<VertexId>(std::min(i, j)),
                            static_cast<VertexId>(std::max(i, j)));
      }
    }
  }
  std::sort(strong.begin(), strong.end(), [](const auto& a, const auto& b) {
    if (std::get<0>(a) != std::get<0>(b)) {
      return std::get<0>(a) > std::get<0>(b);
    }
    return std::tie(std::get<1>(a), std::get<2>(a)) < std::tie(std::get<1>(b), std::get<2>(b));
  });
  for (const auto& [strength, a, b] : strong) {
    const VertexId ra = root(a);
    const VertexId rb = root(b);
    if (ra == rb || size_[static_cast<std::size_t>(ra)] + size_[static_cast<std::size_t>(rb)] >
                        options_.max_size) {
      continue;
    }
    const VertexId low = std::min(ra, rb);
    const VertexId high = std::max(ra, rb);
    parent_[static_cast<std::size_t>(high)] = low;
    size_[static_cast<std::size_t>(low)] += size_[static_cast<std::size_t>(high)];
  }
}

void ClusterJacobi::group(const BlockSparseMatrix& matrix, std::span<const char> constrained,
                          std::size_t first_new) {
  const std::size_t n = matrix.rows();
  std::vector<char> regroup(n, first_new == 0 ? 1 : 0);
  if (first_new > 0) {
    // An edit changes the couplings around its new vertices: the clusters there are taken
    // apart and grouped again with the new vertices (a cluster kept whole could straddle the
    // cut, or miss a sliver's corners; measured, keeping them cost 121 CG iterations per
    // cutting frame on the peers' 6k-tet box against 94 for grouping everything again).
    // Clusters away from the edit stay as they were.
    std::vector<char> dissolve(first_new, 0);  // by root
    for (std::size_t i = first_new; i < n; ++i) {
      regroup[i] = 1;
      for (const VertexId j : matrix.row_columns(static_cast<VertexId>(i))) {
        if (static_cast<std::size_t>(j) < first_new) {
          dissolve[static_cast<std::size_t>(root(j))] = 1;
        }
      }
    }
    for (std::size_t i = 0; i < first_new; ++i) {
      regroup[i] = dissolve[static_cast<std::size_t>(root(static_cast<VertexId>(i)))];
    }
  }
  parent_.resize(n);
  size_.resize(n, 1);
  for (std::size_t i = 0; i < n; ++i) {
    if (regroup[i] != 0) {
      parent_[i] = static_cast<VertexId>(i);
      size_[i] = 1;
    }
  }
  join_strong_pairs(matrix, constrained, regroup);
  pack(matrix, constrained);
}

void ClusterJacobi::pack(const BlockSparseMatrix& matrix, std::span<const char> constrained) {
  const std::size_t n = matrix.rows();
  auto is_free = [&](std::size_t v) { return constrained[v] == 0; };
  // Clusters in the order of their smallest vertex, members in vertex order: numbered by a
  // first pass, counted, then filled by a counting sort (no list per cluster: after a cut this
  // runs every frame, and most of a large body's clusters are single vertices).
  std::vector<std::size_t> cluster_of_root(n, kNoBlock);
  std::vector<std::size_t> cluster_of(n, kNoBlock);
  first_.assign(1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!is_free(i)) {
      continue;
    }
    const auto r = static_cast<std::size_t>(root(static_cast<VertexId>(i)));
    if (cluster_of_root[r] == kNoBlock) {
      cluster_of_root[r] = first_.size() - 1;
      first_.push_back(0);
    }
    cluster_of[i] = cluster_of_root[r];
    ++first_[cluster_of[i] + 1];
  }
  std::partial_sum(first_.begin(), first_.end(), first_.begin());
  members_.resize(first_.back());
  std::vector<std::size_t> next(first_.begin(), first_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    if (cluster_of[i] != kNoBlock) {
      members_[next[cluster_of[i]]++] = static_cast<VertexId>(i);
    }
  }
  multi_.clear();
  offset_.clear();
  block_of_.clear();
  block_first_.clear();
  clustered_vertices_ = 0;
  largest_ = 1;
  std::size_t offset = 0;
  for (std::size_t c = 0; c + 1 < first_.size(); ++c) {
    const std::size_t k = first_[c + 1] - first_[c];
    if (k < 2) {
      continue;
    }
    const std::span<const VertexId> cluster(&members_[first_[c]], k);
    multi_.push_back(c);
    offset_.push_back(offset);
    offset += 9 * k * k;
    block_first_.push_back(block_of_.size());
    clustered_vertices_ += k;
    largest_ = std::max(largest_, k);
    for (const VertexId a : cluster) {
      for (const VertexId b : cluster) {
        block_of_.push_back(matrix.find_if_coupled(a, b).value_or(kNoBlock));
      }
    }
  }
  // Kept with room (core/growth.hpp): after a cut this runs every frame, and an exact-size
  // assign reallocated the inverses whenever the clusters grew, each time in fresh pages
  // (56 % of the page faults of a 220-frame cutting session, BENCHMARKS.md).
  inverse_.clear();
  resize_for_edits(inverse_, offset, 0.0);
  single_inverse_.resize(n);  // every entry is set by update()
}

void ClusterJacobi::save_state(StateWriter& out) const {
  out.tag("clusters");
  out.values(parent_);
  out.values(size_);
  out.values(constrained_);
}

void ClusterJacobi::load_state(StateReader& in) {
  in.tag("clusters");
  std::vector<VertexId> parent = in.values<VertexId>("cluster parents");
  std::vector<std::size_t> size = in.values<std::size_t>("cluster sizes");
  std::vector<char> constrained = in.values<char>("clusters' held rows");
  const std::size_t n = parent.size();
  // A union-find whose roots are each cluster's smallest vertex, sizes within bounds.
  bool valid = size.size() == n && constrained.size() >= n;
  for (std::size_t i = 0; valid && i < n; ++i) {
    valid =
        parent[i] >= 0 && static_cast<std::size_t>(parent[i]) <= i && size[i] >= 1 && size[i] <= n;
  }
  if (!valid) {
    throw InputError("checkpoint: the clusters of the two-level preconditioner are corrupt");
  }
  parent_ = std::move(parent);
  size_ = std::move(size);
  constrained_ = std::move(constrained);
  // The pattern is a new one after a resume: the next update() groups the vertices added
  // since (none, if the mesh did not change) and packs the clusters kept, as it would have.
  pattern_.reset();
  pattern_version_ = 0;
}

bool ClusterJacobi::update(const BlockSparseMatrix& matrix, std::span<const char> constrained) {
  const bool same_pattern =
      pattern_ == matrix.pattern() && pattern_version_ == matrix.pattern_version();
  const bool same_constraints =
      std::equal(constrained.begin(), constrained.end(), constrained_.begin(), constrained_.end());
  if (!same_pattern || !same_constraints) {
    // After a cut only the new vertices' pairs are looked at (the clusters follow the edit,
    // not the body); anything else (new held rows, fewer rows) groups everything again.
    const bool grows = !parent_.empty() && matrix.rows() >= parent_.size() &&
                       constrained.size() >= constrained_.size() &&
                       std::equal(constrained_.begin(), constrained_.end(), constrained.begin());
    group(matrix, constrained, grows ? parent_.size() : 0);
    pattern_ = matrix.pattern();
    pattern_version_ = matrix.pattern_version();
    constrained_.assign(constrained.begin(), constrained.end());
  }
  const auto values = matrix.values();
  std::vector<char> failed(multi_.size(), 0);
  std::atomic<bool> single_failed = false;
  // Vertices alone: their 3x3 inverse (rows in parallel).
  parallel_for(0, single_inverse_.size(), 1024, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      single_inverse_[i].setZero();
    }
  });
  const std::size_t clusters = cluster_count();
  parallel_for(0, clusters, 1024, [&](std::size_t first, std::size_t last) {
    for (std::size_t c = first; c != last; ++c) {
      if (first_[c + 1] - first_[c] != 1) {
        continue;
      }
      const VertexId v = members_[first_[c]];
      const Mat3& d = values[matrix.diagonal(v)];
      if (!(d.determinant() > 0.0)) {
        single_failed = true;
      }
      single_inverse_[static_cast<std::size_t>(v)] = d.inverse();
    }
  });
  // Clusters: each block factorised and inverted in place (a buffer per task, no allocation
  // per cluster).
  parallel_for(0, multi_.size(), 64, [&](std::size_t first, std::size_t last) {
    const auto largest = static_cast<Eigen::Index>(3 * largest_);
    Eigen::MatrixXd buffer(largest, largest);
    for (std::size_t m = first; m != last; ++m) {
      const std::size_t c = multi_[m];
      const std::size_t k = first_[c + 1] - first_[c];
      const auto size = static_cast<Eigen::Index>(3 * k);
      auto block = buffer.topLeftCorner(size, size);
      block.setZero();
      for (std::size_t a = 0; a < k; ++a) {
        for (std::size_t b = 0; b < k; ++b) {
          const std::size_t index = block_of_[block_first_[m] + a * k + b];
          if (index != kNoBlock) {
            block.block<3, 3>(static_cast<Eigen::Index>(3 * a), static_cast<Eigen::Index>(3 * b)) =
                values[index];
          }
        }
      }
      Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> factor(block);
      if (factor.info() != Eigen::Success) {
        failed[m] = 1;
        continue;
      }
      Eigen::Map<Eigen::MatrixXd> inverse(&inverse_[offset_[m]], size, size);
      inverse.setIdentity();
      factor.solveInPlace(inverse);
    }
  });
  return !single_failed &&
         std::none_of(failed.begin(), failed.end(), [](char f) { return f != 0; });
}

namespace {

/// One cluster of k vertices: z = inverse r on its members; returns their part of r.z.
/// `gathered` and `solved` hold 3k numbers: fixed-size vectors for the sizes the default limit
/// allows, so that Eigen unrolls and vectorises the product (a dynamic-size product of these
/// small matrices spent most of its time setting itself up), else per-task buffers of the
/// largest cluster's size (no allocation per cluster).
template <typename Vector>
double apply_cluster(const double* inverse, const VertexId* members, std::size_t k,
                     std::span<const Vec3> r, std::span<Vec3> z, Vector& gathered, Vector& solved) {
  for (std::size_t a = 0; a < k; ++a) {
    gathered.template segment<3>(static_cast<Eigen::Index>(3 * a)) =
        r[static_cast<std::size_t>(members[a])];
  }
  constexpr int kRows = Vector::RowsAtCompileTime;
  if constexpr (kRows == Eigen::Dynamic) {
    const auto size = static_cast<Eigen::Index>(3 * k);
    solved.head(size).noalias() =
        Eigen::Map<const Eigen::MatrixXd>(inverse, size, size) * gathered.head(size);
  } else {
    solved.noalias() = Eigen::Map<const Eigen::Matrix<double, kRows, kRows>>(inverse) * gathered;
  }
  double sum = 0.0;
  for (std::size_t a = 0; a < k; ++a) {
    const auto v = static_cast<std::size_t>(members[a]);
    z[v] = solved.template segment<3>(static_cast<Eigen::Index>(3 * a));
    sum += r[v].dot(z[v]);
  }
  return sum;
}

/// apply_cluster for a cluster of K vertices, with fixed-size vectors.
template <int K>
double apply_fixed_size_cluster(const double* inverse, const VertexId* members,
                                std::span<const Vec3> r, std::span<Vec3> z) {
  Eigen::Matrix<double, 3 * K, 1> gathered;
  Eigen::Matrix<double, 3 * K, 1> solved;
  return apply_cluster(inverse, members, K, r, z, gathered, solved);
}

using FixedSizeApply = double (*)(const double*, const VertexId*, std::span<const Vec3>,
                                  std::span<Vec3>);
/// By cluster size: the default limit's sizes, 2 to 8 vertices (0 and 1 never form a cluster).
constexpr std::array<FixedSizeApply, 9> kFixedSizeApply = {nullptr,
                                                           nullptr,
                                                           &apply_fixed_size_cluster<2>,
                                                           &apply_fixed_size_cluster<3>,
                                                           &apply_fixed_size_cluster<4>,
                                                           &apply_fixed_size_cluster<5>,
                                                           &apply_fixed_size_cluster<6>,
                                                           &apply_fixed_size_cluster<7>,
                                                           &apply_fixed_size_cluster<8>};

}  // namespace

double ClusterJacobi::apply_clusters(std::span<const Vec3> r, std::span<Vec3> z) const {
  const std::size_t clusters = multi_.size();
  const std::size_t chunks = (clusters + kClusterChunk - 1) / kClusterChunk;
  std::vector<double> partial(chunks, 0.0);
  parallel_for(0, chunks, 1, [&](std::size_t first_chunk, std::size_t last_chunk) {
    const auto largest = static_cast<Eigen::Index>(3 * largest_);
    Eigen::VectorXd gathered(largest);
    Eigen::VectorXd solved(largest);
    for (std::size_t chunk = first_chunk; chunk != last_chunk; ++chunk) {
      double sum = 0.0;
      const std::size_t end = std::min(clusters, (chunk + 1) * kClusterChunk);
      for (std::size_t m = chunk * kClusterChunk; m < end; ++m) {
        const std::size_t c = multi_[m];
        const std::size_t k = first_[c + 1] - first_[c];
        const double* inverse = &inverse_[offset_[m]];
        const VertexId* members = &members_[first_[c]];
        if (k < kFixedSizeApply.size()) {
          sum += kFixedSizeApply[k](inverse, members, r, z);
        } else {
          sum += apply_cluster(inverse, members, k, r, z, gathered, solved);
        }
      }
      partial[chunk] = sum;
    }
  });
  return std::accumulate(partial.begin(), partial.end(), 0.0);
}

}  // namespace incise
