#include "incise/solve/aggregation_coarse_space.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/solve/direct_factorization.hpp"

namespace incise {

AggregationCoarseSpace::AggregationCoarseSpace()
    : factor_(std::make_unique<DirectFactorization>()) {}

AggregationCoarseSpace::~AggregationCoarseSpace() = default;

namespace {

/// values = `size` copies of `fill`, in the pages `values` already holds while they suffice,
/// else with room for twice `size`. The aggregation runs again every tenth step of a body
/// being cut, each time a little larger: an exact-size assign() mapped fresh pages every time
/// (350-960 page faults per aggregation on the 50k body, about 12 us each on the 2-core VM:
/// most of its 7-15 ms; BENCHMARKS.md).
template <typename T>
void refill(std::vector<T>& values, std::size_t size, const T& fill) {
  values.clear();
  resize_for_edits(values, size, fill);
}

/// Room for `size` elements in `values`: twice that if it must grow.
template <typename T>
void reserve_at_least(std::vector<T>& values, std::size_t size) {
  if (size > values.capacity()) {
    values.reserve(capacity_for_edits(size));
  }
}

/// A weighted graph in compressed rows (no self loops).
struct Graph {
  std::vector<std::size_t> first{0};
  std::vector<int> node;
  std::vector<double> weight;
  [[nodiscard]] std::size_t size() const { return first.size() - 1; }
};

/// Greedy aggregation (Vanek, Mandel and Brezina 1996) of the eligible nodes: a node whose
/// eligible neighbours are all unclaimed founds an aggregate with them (about one ring, spread
/// without overlap); the rest join the founded aggregate they are most strongly tied to (so
/// aggregates do not creep); nodes with none beside them group with their unclaimed
/// neighbours. Returns each node's aggregate (-1 where not eligible) and the count.
std::pair<std::vector<int>, int> greedy_aggregates(const Graph& graph,
                                                   const std::vector<char>& eligible) {
  const std::size_t n = graph.size();
  std::vector<int> aggregate(n, -1);
  int count = 0;
  auto neighbours = [&](std::size_t i) {
    return std::span<const int>(graph.node)
        .subspan(graph.first[i], graph.first[i + 1] - graph.first[i]);
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (eligible[i] == 0 || aggregate[i] >= 0) {
      continue;
    }
    const auto around = neighbours(i);
    if (!std::all_of(around.begin(), around.end(), [&](int j) {
          return eligible[static_cast<std::size_t>(j)] == 0 ||
                 aggregate[static_cast<std::size_t>(j)] < 0;
        })) {
      continue;
    }
    aggregate[i] = count;
    for (const int j : around) {
      if (eligible[static_cast<std::size_t>(j)] != 0) {
        aggregate[static_cast<std::size_t>(j)] = count;
      }
    }
    ++count;
  }
  const std::vector<int> founded = aggregate;
  for (std::size_t i = 0; i < n; ++i) {
    if (eligible[i] == 0 || founded[i] >= 0) {
      continue;
    }
    double strongest = -1.0;
    for (std::size_t k = graph.first[i]; k < graph.first[i + 1]; ++k) {
      const int other = founded[static_cast<std::size_t>(graph.node[k])];
      if (other >= 0 && graph.weight[k] > strongest) {
        strongest = graph.weight[k];
        aggregate[i] = other;
      }
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (eligible[i] == 0 || aggregate[i] >= 0) {
      continue;
    }
    aggregate[i] = count;
    for (const int j : neighbours(i)) {
      if (eligible[static_cast<std::size_t>(j)] != 0 &&
          aggregate[static_cast<std::size_t>(j)] < 0) {
        aggregate[static_cast<std::size_t>(j)] = count;
      }
    }
    ++count;
  }
  return {std::move(aggregate), count};
}

using ModeMatrix = AggregationCoarseSpace::ModeMatrix;
using Modes = AggregationCoarseSpace::Modes;
using VertexModes = AggregationCoarseSpace::VertexModes;
constexpr int kModes = AggregationCoarseSpace::kModes;
/// Per task in the coarse solve's passes: aggregates (some 1,500 vertices), or top-level groups
/// (some 20 aggregates each).
constexpr std::size_t kAggregateGrain = 64;
constexpr std::size_t kGroupGrain = 4;
/// Vertices per chunk of the restriction's first pass (fixed, so the sums are the same on any
/// thread count).
constexpr std::size_t kRestrictChunk = 2048;
/// The damped V-cycle smoother's largest eigenvalue on P^T A P at most (below 2, where the cycle
/// would stop being positive definite).
constexpr double kSmootherReach = 1.6;

/// first[k] .. first[k + 1]: where the entries with key k (0 <= k < keys) start and end once
/// sorted by key.
void key_offsets(std::span<const int> key, std::size_t keys, std::vector<std::size_t>& first) {
  first.assign(keys + 1, 0);
  for (const int k : key) {
    ++first[static_cast<std::size_t>(k) + 1];
  }
  for (std::size_t k = 0; k < keys; ++k) {
    first[k + 1] += first[k];
  }
}

/// The indices of `key` grouped by key (a counting sort): key k's at items[first[k] ..
/// first[k + 1]), in increasing order.
void group_by_key(std::span<const int> key, std::size_t keys, std::vector<std::size_t>& first,
                  std::vector<int>& items) {
  key_offsets(key, keys, first);
  items.resize(key.size());
  std::vector<std::size_t> next(first.begin(), first.end() - 1);
  for (std::size_t i = 0; i < key.size(); ++i) {
    items[next[static_cast<std::size_t>(key[i])]++] = static_cast<int>(i);
  }
}

/// A displacement field's rigid coordinates: translation (m) and small rotation about a centre:
/// u(x) = t + w x (x - centre) = [I, -[x - centre]x] (t, w).
VertexModes raw_rigid_modes(const Vec3& offset_from_centre) {
  VertexModes modes;
  modes.leftCols<3>().setIdentity();
  modes.rightCols<3>() = -cross_matrix(offset_from_centre);
  return modes;
}

/// block += R_i^T a R_j with R_v = raw_rigid_modes(d_v): [[a, -a [d_j]x], [[d_i]x a,
/// -[d_i]x a [d_j]x]], by columns and rows crossed with the offsets. Row r of -a [d_j]x is
/// d_j x (row r of a), column c of [d_i]x a is d_i x (column c of a).
void add_rigid_block(const Mat3& a, const Vec3& offset_i, const Vec3& offset_j,
                     Eigen::Matrix<double, 6, 6>& block) {
  Mat3 turned;  // [d_i]x a
  for (int c = 0; c < 3; ++c) {
    turned.col(c) = offset_i.cross(a.col(c));
  }
  block.topLeftCorner<3, 3>() += a;
  block.bottomLeftCorner<3, 3>() += turned;
  for (int r = 0; r < 3; ++r) {
    block.block<1, 3>(r, 3) += offset_j.cross(Vec3(a.row(r).transpose())).transpose();
    block.block<1, 3>(3 + r, 3) += offset_j.cross(Vec3(turned.row(r).transpose())).transpose();
  }
}

/// Orthonormal modes of a span with Gram matrix `gram` (raw coordinates): W with
/// W^T gram W = I on the kept modes and zero columns for the dropped ones, and its
/// pseudo-inverse. Scaled to unit diagonal first, so metres and radians compare; modes below
/// 1e-6 of the largest eigenvalue are dropped (a rotation the members cannot carry).
struct OrthonormalModes {
  ModeMatrix raw_from_modes = ModeMatrix::Zero();
  ModeMatrix modes_from_raw = ModeMatrix::Zero();
  unsigned dropped = 0;
};
OrthonormalModes orthonormal_modes(const ModeMatrix& gram) {
  constexpr double kDropBelow = 1e-6;
  Modes scale;
  for (int k = 0; k < kModes; ++k) {
    scale[k] = gram(k, k) > 0.0 ? 1.0 / std::sqrt(gram(k, k)) : 0.0;
  }
  const ModeMatrix scaled = scale.asDiagonal() * gram * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<ModeMatrix> eigen(scaled);
  const double largest = eigen.eigenvalues().maxCoeff();
  OrthonormalModes result;
  for (int k = 0; k < kModes; ++k) {
    const double lambda = eigen.eigenvalues()[k];
    if (!(largest > 0.0) || !(lambda > kDropBelow * largest)) {
      result.dropped |= 1U << static_cast<unsigned>(k);
      continue;
    }
    const Modes v = eigen.eigenvectors().col(k);
    result.raw_from_modes.col(k) = scale.asDiagonal() * v / std::sqrt(lambda);
    for (int c = 0; c < kModes; ++c) {
      result.modes_from_raw(k, c) = scale[c] > 0.0 ? std::sqrt(lambda) * v[c] / scale[c] : 0.0;
    }
  }
  return result;
}

/// A coarse diagonal block's dropped modes get a diagonal entry of the kept ones' mean
/// (their rows are zero: the block stays positive definite and the mode's correction zero).
void fill_dropped(ModeMatrix& block, unsigned dropped) {
  double kept_sum = 0.0;
  int kept = 0;
  for (int k = 0; k < kModes; ++k) {
    if ((dropped & (1U << static_cast<unsigned>(k))) == 0) {
      kept_sum += block(k, k);
      ++kept;
    }
  }
  const double fill = kept > 0 && kept_sum > 0.0 ? kept_sum / kept : 1.0;
  for (int k = 0; k < kModes; ++k) {
    if ((dropped & (1U << static_cast<unsigned>(k))) != 0) {
      block(k, k) = fill;
    }
  }
}

}  // namespace

void AggregationCoarseSpace::aggregate(const BlockSparseMatrix& matrix,
                                       std::span<const char> constrained) {
  const std::size_t n = matrix.rows();
  const auto values = matrix.values();
  // The free vertices' graph, tied by the squared norm of their blocks, built in the last
  // aggregation's arrays (their pages stay mapped).
  Graph graph;
  graph.first = std::move(graph_first_);
  graph.node = std::move(graph_node_);
  graph.weight = std::move(graph_weight_);
  graph.first.assign(1, 0);
  graph.node.clear();
  graph.weight.clear();
  reserve_at_least(graph.node, values.size());
  reserve_at_least(graph.weight, values.size());
  std::vector<char> eligible(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    eligible[i] = constrained[i] == 0 ? 1 : 0;
    if (eligible[i] != 0) {
      const auto row = matrix.row_columns(static_cast<VertexId>(i));
      const std::size_t first = matrix.row_begin()[i];
      for (std::size_t k = 0; k < row.size(); ++k) {
        const auto j = static_cast<std::size_t>(row[k]);
        if (j != i && constrained[j] == 0) {
          graph.node.push_back(row[k]);
          graph.weight.push_back(values[first + k].squaredNorm());
        }
      }
    }
    graph.first.push_back(graph.node.size());
  }
  auto [aggregate, count] = greedy_aggregates(graph, eligible);
  graph_first_ = std::move(graph.first);
  graph_node_ = std::move(graph.node);
  graph_weight_ = std::move(graph.weight);
  // (Aggregating the aggregates once more made the coarse solve 8x smaller but needed 1.6x the
  // iterations on the 384k-tet box: slower in all, measured.)
  aggregate_of_ = std::move(aggregate);
  members_.resize(static_cast<std::size_t>(count));  // each emptied and filled again
  collect_members();

  // The coarse pattern: aggregate I couples to J when a block of A joins a member of each.
  // Slots are numbered row by row with sorted columns, so the scalar matrix comes out sorted.
  const std::size_t aggregates = members_.size();
  refill(coarse_slot_, matrix.values().size(), -1);
  std::vector<int> seen(aggregates, -1);
  std::vector<int> slot_of(aggregates, -1);
  std::vector<int> neighbours;
  std::vector<std::vector<int>> coarse_columns(aggregates);
  int slots = 0;
  slot_row_.clear();
  slot_column_.clear();
  for (std::size_t a = 0; a < aggregates; ++a) {
    neighbours.clear();
    for (const VertexId v : members_[a]) {
      for (const VertexId j : matrix.row_columns(v)) {
        const int b = aggregate_of_[static_cast<std::size_t>(j)];
        if (b >= 0 && seen[static_cast<std::size_t>(b)] != static_cast<int>(a)) {
          seen[static_cast<std::size_t>(b)] = static_cast<int>(a);
          neighbours.push_back(b);
        }
      }
    }
    std::sort(neighbours.begin(), neighbours.end());
    for (const int b : neighbours) {
      slot_of[static_cast<std::size_t>(b)] = slots++;
      slot_row_.push_back(static_cast<int>(a));
      slot_column_.push_back(b);
    }
    for (const VertexId v : members_[a]) {
      const std::size_t first = matrix.row_begin()[static_cast<std::size_t>(v)];
      const auto row = matrix.row_columns(v);
      for (std::size_t k = 0; k < row.size(); ++k) {
        const int b = aggregate_of_[static_cast<std::size_t>(row[k])];
        if (b >= 0) {
          coarse_slot_[first + k] = slot_of[static_cast<std::size_t>(b)];
        }
      }
    }
    coarse_columns[a] = neighbours;
  }
  slots_by_row_.clear();
  reserve_at_least(slots_by_row_, matrix.values().size());
  for (std::size_t i = 0; i < matrix.rows(); ++i) {
    for (std::size_t k = matrix.row_begin()[i]; k < matrix.row_end()[i]; ++k) {
      slots_by_row_.push_back(coarse_slot_[k]);
    }
  }
  placed_pattern_ = matrix.pattern();
  placed_version_ = matrix.pattern_version();
  refill(coarse_blocks_, static_cast<std::size_t>(slots), ModeMatrix(ModeMatrix::Zero()));
  diagonal_slot_.assign(aggregates, -1);
  for (std::size_t a = 0, row_slot = 0; a < aggregates; row_slot += coarse_columns[a].size(), ++a) {
    const auto found =
        std::lower_bound(coarse_columns[a].begin(), coarse_columns[a].end(), static_cast<int>(a));
    diagonal_slot_[a] =
        static_cast<int>(row_slot + static_cast<std::size_t>(found - coarse_columns[a].begin()));
  }

  collect_slot_rows();

  // A large coarse system costs more to solve than a product at every iteration (7,600
  // unknowns on the 384k-tet box: 4 ms against 3.5). Above exact_limit_ unknowns the
  // aggregates are aggregated once more: their level gets its block-Jacobi, and only the top
  // level is factorised (a V-cycle over the two, see solve()).
  three_level_ = kModes * aggregates > exact_limit_;
  std::vector<std::vector<int>> top_columns;
  if (three_level_) {
    Graph aggregate_graph;
    for (std::size_t a = 0; a < aggregates; ++a) {
      for (const int b : coarse_columns[a]) {
        if (b != static_cast<int>(a)) {
          aggregate_graph.node.push_back(b);
          aggregate_graph.weight.push_back(1.0);
        }
      }
      aggregate_graph.first.push_back(aggregate_graph.node.size());
    }
    auto [top, top_count] = greedy_aggregates(aggregate_graph, std::vector<char>(aggregates, 1));
    top_of_ = std::move(top);
    collect_top_members(static_cast<std::size_t>(top_count));
    top_columns.assign(static_cast<std::size_t>(top_count), {});
    for (std::size_t a = 0; a < aggregates; ++a) {
      auto& row = top_columns[static_cast<std::size_t>(top_of_[a])];
      for (const int b : coarse_columns[a]) {
        row.push_back(top_of_[static_cast<std::size_t>(b)]);
      }
    }
    for (auto& row : top_columns) {
      std::sort(row.begin(), row.end());
      row.erase(std::unique(row.begin(), row.end()), row.end());
    }
    // Each level-1 slot (a, b) adds into top slot (top(a), top(b)).
    std::vector<int> top_row_slot(top_columns.size() + 1, 0);
    for (std::size_t t = 0; t < top_columns.size(); ++t) {
      top_row_slot[t + 1] = top_row_slot[t] + static_cast<int>(top_columns[t].size());
    }
    top_slot_.assign(static_cast<std::size_t>(slots), -1);
    for (std::size_t a = 0, s1 = 0; a < aggregates; ++a) {
      const auto t = static_cast<std::size_t>(top_of_[a]);
      for (const int b : coarse_columns[a]) {
        const int u = top_of_[static_cast<std::size_t>(b)];
        const auto found = std::lower_bound(top_columns[t].begin(), top_columns[t].end(), u);
        top_slot_[s1++] = top_row_slot[t] + static_cast<int>(found - top_columns[t].begin());
      }
    }
    top_diagonal_slot_.assign(top_columns.size(), -1);
    for (std::size_t t = 0; t < top_columns.size(); ++t) {
      const auto found =
          std::lower_bound(top_columns[t].begin(), top_columns[t].end(), static_cast<int>(t));
      top_diagonal_slot_[t] = top_row_slot[t] + static_cast<int>(found - top_columns[t].begin());
    }
    refill(top_blocks_, static_cast<std::size_t>(top_row_slot.back()),
           ModeMatrix(ModeMatrix::Zero()));
    refill(own_inverse_, aggregates, ModeMatrix(ModeMatrix::Zero()));
    refill(top_map_, aggregates, ModeMatrix(ModeMatrix::Zero()));
    top_dropped_.assign(top_columns.size(), 0);
  } else {
    top_of_.clear();
    collect_top_members(0);
    top_slot_.clear();
    top_blocks_.clear();
    own_inverse_.clear();
    top_map_.clear();
    top_dropped_.clear();
  }
  const std::vector<std::vector<int>>& factored_columns =
      three_level_ ? top_columns : coarse_columns;

  // Scalar column 6a + c holds, for each coupled b and each r, entry (6b + r, 6a + c) =
  // block(b, a)(r, c) = block(a, b)(c, r) (the matrix is symmetric): offset 6 r + c of the
  // column-major block (a, b).
  const std::size_t rows = factored_columns.size();
  const auto unknowns = static_cast<int>(kModes * rows);
  std::vector<int> outer(static_cast<std::size_t>(unknowns) + 1, 0);
  std::vector<int> inner;
  scalar_source_.clear();
  int slot = 0;
  for (std::size_t a = 0; a < rows; ++a) {
    const int row_slot = slot;
    for (int c = 0; c < kModes; ++c) {
      int s = row_slot;
      for (const int b : factored_columns[a]) {
        for (int r = 0; r < kModes; ++r) {
          inner.push_back(kModes * b + r);
          scalar_source_.emplace_back(s, kModes * r + c);
        }
        ++s;
      }
      outer[kModes * a + static_cast<std::size_t>(c) + 1] = static_cast<int>(inner.size());
    }
    slot += static_cast<int>(factored_columns[a].size());
  }
  scalar_.resize(unknowns, unknowns);
  scalar_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), scalar_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), scalar_.innerIndexPtr());
  refill(coarse_motion_, aggregates, Modes(Modes::Zero()));
}

Vec3 AggregationCoarseSpace::offset_in(std::size_t aggregate, std::span<const Vec3> positions,
                                       std::size_t vertex) const {
  return positions.empty() ? Vec3::Zero() : Vec3(positions[vertex] - centre_[aggregate]);
}

void AggregationCoarseSpace::shape_modes(std::span<const Vec3> positions) {
  const std::size_t aggregates = members_.size();
  const std::size_t n = aggregate_of_.size();
  offset_.resize(n);
  centre_.assign(aggregates, Vec3::Zero());
  raw_from_modes_.resize(aggregates);
  modes_from_raw_.resize(aggregates);
  dropped_.resize(aggregates);
  parallel_for(0, aggregates, 64, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      const auto& group = members_[a];
      Vec3 centre = Vec3::Zero();
      if (!positions.empty()) {
        for (const VertexId v : group) {
          centre += positions[static_cast<std::size_t>(v)];
        }
        centre /= static_cast<double>(group.size());
      }
      centre_[a] = centre;
      ModeMatrix gram = ModeMatrix::Zero();
      for (const VertexId v : group) {
        const auto i = static_cast<std::size_t>(v);
        offset_[i] = offset_in(a, positions, i);
        const VertexModes raw = raw_rigid_modes(offset_[i]);
        gram += raw.transpose() * raw;
      }
      const OrthonormalModes modes = orthonormal_modes(gram);
      raw_from_modes_[a] = modes.raw_from_modes;
      modes_from_raw_[a] = modes.modes_from_raw;
      dropped_[a] = modes.dropped;
    }
  });
  for (std::size_t v = 0; v < n; ++v) {
    if (aggregate_of_[v] < 0) {
      offset_[v].setZero();
    }
  }
  if (!three_level_) {
    return;
  }
  // A group's rigid motion (t, w) about its centre C moves aggregate a rigidly with
  // (t + w x (c_a - C), w): its modes' coordinates are modes_from_raw_a of that.
  const std::size_t groups = top_dropped_.size();
  std::vector<Vec3> group_centre(groups, Vec3::Zero());
  std::vector<double> group_weight(groups, 0.0);
  for (std::size_t a = 0; a < aggregates; ++a) {
    const auto t = static_cast<std::size_t>(top_of_[a]);
    const auto weight = static_cast<double>(members_[a].size());
    group_centre[t] += weight * centre_[a];
    group_weight[t] += weight;
  }
  for (std::size_t t = 0; t < groups; ++t) {
    group_centre[t] /= std::max(group_weight[t], 1.0);
  }
  std::vector<ModeMatrix> gram(groups, ModeMatrix::Zero());
  for (std::size_t a = 0; a < aggregates; ++a) {
    const auto t = static_cast<std::size_t>(top_of_[a]);
    ModeMatrix raw_from_group = ModeMatrix::Identity();
    raw_from_group.topRightCorner<3, 3>() = -cross_matrix(centre_[a] - group_centre[t]);
    top_map_[a] = modes_from_raw_[a] * raw_from_group;
    gram[t] += top_map_[a].transpose() * top_map_[a];
  }
  std::vector<ModeMatrix> group_modes(groups);
  for (std::size_t t = 0; t < groups; ++t) {
    const OrthonormalModes modes = orthonormal_modes(gram[t]);
    group_modes[t] = modes.raw_from_modes;
    top_dropped_[t] = modes.dropped;
  }
  for (std::size_t a = 0; a < aggregates; ++a) {
    top_map_[a] = top_map_[a] * group_modes[static_cast<std::size_t>(top_of_[a])];
  }
}

void AggregationCoarseSpace::extend(const BlockSparseMatrix& matrix,
                                    std::span<const char> constrained,
                                    std::span<const Vec3> positions) {
  // New vertices (a cut) join the aggregate of their most strongly coupled neighbour that has
  // one; vertices held since are dropped. The aggregates, and so the factor, stay as they are:
  // a vertex with no aggregate beside it gets no coarse correction until the next
  // refactorisation.
  const std::size_t n = matrix.rows();
  aggregate_of_.resize(n, -1);
  offset_.resize(n, Vec3::Zero());
  const auto values = matrix.values();
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained[i] != 0) {
      aggregate_of_[i] = -1;
      offset_[i].setZero();
      continue;
    }
    if (aggregate_of_[i] >= 0) {
      continue;
    }
    const auto row = matrix.row_columns(static_cast<VertexId>(i));
    const std::size_t first = matrix.row_begin()[i];
    double strongest = -1.0;
    for (std::size_t k = 0; k < row.size(); ++k) {
      const int other = aggregate_of_[static_cast<std::size_t>(row[k])];
      if (other >= 0 && constrained[static_cast<std::size_t>(row[k])] == 0 &&
          values[first + k].squaredNorm() > strongest) {
        strongest = values[first + k].squaredNorm();
        aggregate_of_[i] = other;
      }
    }
    offset_[i] = aggregate_of_[i] < 0
                     ? Vec3::Zero()
                     : offset_in(static_cast<std::size_t>(aggregate_of_[i]), positions, i);
  }
  collect_members();
}

void AggregationCoarseSpace::collect_members() {
  for (std::vector<VertexId>& group : members_) {
    group.clear();
  }
  for (std::size_t i = 0; i < aggregate_of_.size(); ++i) {
    if (aggregate_of_[i] >= 0) {
      members_[static_cast<std::size_t>(aggregate_of_[i])].push_back(static_cast<VertexId>(i));
    }
  }
  collect_partials();
}

void AggregationCoarseSpace::collect_partials() {
  // One partial sum per aggregate and chunk of vertices it has members in, numbered chunk by
  // chunk; each aggregate's partials in chunk order.
  const std::size_t n = aggregate_of_.size();
  const std::size_t aggregates = members_.size();
  const std::size_t chunks = (n + kRestrictChunk - 1) / kRestrictChunk;
  partial_of_.resize(n);
  chunk_partial_first_.assign(chunks + 1, 0);
  std::vector<int> partial_aggregate;
  std::vector<std::size_t> last_chunk(aggregates, chunks);
  std::vector<int> last_partial(aggregates, -1);
  for (std::size_t c = 0; c < chunks; ++c) {
    for (std::size_t i = c * kRestrictChunk; i < std::min(n, (c + 1) * kRestrictChunk); ++i) {
      const int a = aggregate_of_[i];
      if (a < 0) {
        partial_of_[i] = -1;
        continue;
      }
      const auto aggregate = static_cast<std::size_t>(a);
      if (last_chunk[aggregate] != c) {
        last_chunk[aggregate] = c;
        last_partial[aggregate] = static_cast<int>(partial_aggregate.size());
        partial_aggregate.push_back(a);
      }
      partial_of_[i] = last_partial[aggregate];
    }
    chunk_partial_first_[c + 1] = partial_aggregate.size();
  }
  group_by_key(partial_aggregate, aggregates, aggregate_partial_first_, aggregate_partials_);
  partial_sums_.resize(partial_aggregate.size());
}

void AggregationCoarseSpace::collect_top_members(std::size_t groups) {
  group_by_key(top_of_, groups, top_first_, top_members_);
}

std::uint64_t AggregationCoarseSpace::pattern_hash(const BlockSparseMatrix& matrix) {
  if (hashed_pattern_ == matrix.pattern() && hashed_version_ == matrix.pattern_version()) {
    return hashed_value_;
  }
  // Rows, and each row's columns in order (hash_combine's mixing, on 64-bit words).
  std::uint64_t hash = 0;
  const auto mix = [&hash](std::uint64_t word) {
    hash ^= word + 0x9e3779b97f4a7c15ULL + (hash << 6) + (hash >> 2);
  };
  mix(matrix.rows());
  for (std::size_t i = 0; i < matrix.rows(); ++i) {
    const auto row = matrix.row_columns(static_cast<VertexId>(i));
    mix(row.size());
    for (const VertexId column : row) {
      mix(static_cast<std::uint64_t>(column));
    }
  }
  hashed_pattern_ = matrix.pattern();
  hashed_version_ = matrix.pattern_version();
  hashed_value_ = hash;
  return hash;
}

bool AggregationCoarseSpace::same_as(const Look& look, const BlockSparseMatrix& matrix,
                                     std::span<const char> constrained) {
  return look.taken &&
         std::equal(constrained.begin(), constrained.end(), look.constrained.begin(),
                    look.constrained.end()) &&
         pattern_hash(matrix) == look.hash;
}

void AggregationCoarseSpace::remember(Look& look, const BlockSparseMatrix& matrix,
                                      std::span<const char> constrained) {
  look.taken = true;
  look.hash = pattern_hash(matrix);
  look.constrained.assign(constrained.begin(), constrained.end());
}

void AggregationCoarseSpace::place_slots(const BlockSparseMatrix& matrix) {
  refill(coarse_slot_, matrix.values().size(), -1);
  std::size_t entry = 0;
  for (std::size_t i = 0; i < matrix.rows(); ++i) {
    for (std::size_t k = matrix.row_begin()[i]; k < matrix.row_end()[i]; ++k) {
      INCISE_ASSERT(entry < slots_by_row_.size(), "the aggregated pattern has these blocks");
      coarse_slot_[k] = slots_by_row_[entry++];
    }
  }
  INCISE_ASSERT(entry == slots_by_row_.size(), "the aggregated pattern has these blocks");
  placed_pattern_ = matrix.pattern();
  placed_version_ = matrix.pattern_version();
}

void AggregationCoarseSpace::save_state(StateWriter& out) const {
  out.tag("coarse space");
  out.value(factored_);
  if (!factored_) {
    return;
  }
  out.value(updates_since_factor_);
  out.value(three_level_);
  for (const Look* look : {&aggregated_, &seen_}) {
    out.value(look->taken);
    out.value(look->hash);
    out.values(look->constrained);
  }
  out.values(slots_by_row_);
  out.values(aggregate_of_);
  out.value(static_cast<std::uint64_t>(members_.size()));
  out.values(offset_);
  out.values(centre_);
  out.values(modes_from_raw_);
  out.values(raw_from_modes_);
  out.values(dropped_);
  out.values(top_dropped_);
  out.values(scalar_source_);
  out.values(slot_row_);
  out.values(slot_column_);
  out.values(diagonal_slot_);
  out.values(top_diagonal_slot_);
  out.values(top_of_);
  out.values(top_slot_);
  out.values(top_map_);
  out.values(own_inverse_);
  if (three_level_) {
    out.values(coarse_blocks_);  // the V-cycle's products: P^T A P as last factorised
  }
  out.value(static_cast<std::uint64_t>(coarse_blocks_.size()));
  out.value(static_cast<std::uint64_t>(top_blocks_.size()));
  // The coarse matrix as factorised (the factor is made again from it).
  out.value(static_cast<std::int64_t>(scalar_.rows()));
  out.values(
      std::vector<int>(scalar_.outerIndexPtr(), scalar_.outerIndexPtr() + scalar_.outerSize() + 1));
  out.values(
      std::vector<int>(scalar_.innerIndexPtr(), scalar_.innerIndexPtr() + scalar_.nonZeros()));
  out.values(std::vector<double>(scalar_.valuePtr(), scalar_.valuePtr() + scalar_.nonZeros()));
}

void AggregationCoarseSpace::load_state(StateReader& in) {
  in.tag("coarse space");
  const bool factored = in.value<bool>("coarse space factorised");
  if (!factored) {
    factored_ = false;  // the next update() builds everything
    aggregated_ = {};
    seen_ = {};
    return;
  }
  const int updates = in.value<int>("updates since the coarse factorisation");
  const bool three_level = in.value<bool>("coarse levels");
  Look looks[2];
  for (Look& look : looks) {
    look.taken = in.value<bool>("coarse look taken");
    look.hash = in.value<std::uint64_t>("coarse look pattern");
    look.constrained = in.values<char>("coarse look held rows");
  }
  auto slots_by_row = in.values<int>("coarse slots");
  auto aggregate_of = in.values<int>("aggregates");
  const auto aggregates = in.value<std::uint64_t>("aggregate count");
  auto offset = in.values<Vec3>("aggregate offsets");
  auto centre = in.values<Vec3>("aggregate centres");
  auto modes_from_raw = in.values<ModeMatrix>("aggregate modes");
  auto raw_from_modes = in.values<ModeMatrix>("aggregate motions");
  auto dropped = in.values<unsigned>("aggregate dropped modes");
  auto top_dropped = in.values<unsigned>("group dropped modes");
  auto scalar_source = in.values<std::pair<int, int>>("coarse matrix sources");
  auto slot_row = in.values<int>("coarse slot rows");
  auto slot_column = in.values<int>("coarse slot columns");
  auto diagonal_slot = in.values<int>("coarse diagonal slots");
  auto top_diagonal_slot = in.values<int>("group diagonal slots");
  auto top_of = in.values<int>("aggregate groups");
  auto top_slot = in.values<int>("group slots");
  auto top_map = in.values<ModeMatrix>("group modes");
  auto own_inverse = in.values<ModeMatrix>("aggregate inverses");
  auto coarse_blocks =
      three_level ? in.values<ModeMatrix>("coarse blocks") : std::vector<ModeMatrix>{};
  const auto slots = in.value<std::uint64_t>("coarse slot count");
  const auto top_slots = in.value<std::uint64_t>("group slot count");
  const auto unknowns = in.value<std::int64_t>("coarse unknowns");
  const auto outer = in.values<int>("coarse matrix columns");
  const auto inner = in.values<int>("coarse matrix rows");
  const auto values = in.values<double>("coarse matrix values");

  // The V-cycle finds block (b, a) beside (a, b): slots row by row, each row's columns
  // increasing, and the pattern symmetric.
  const auto symmetric_rows = [](const std::vector<int>& rows, const std::vector<int>& columns) {
    std::vector<std::pair<int, int>> pairs(rows.size());
    for (std::size_t s = 0; s < rows.size(); ++s) {
      pairs[s] = {rows[s], columns[s]};
    }
    if (std::adjacent_find(pairs.begin(), pairs.end(),
                           [](const auto& x, const auto& y) { return !(x < y); }) != pairs.end()) {
      return false;
    }
    return std::all_of(pairs.begin(), pairs.end(), [&](const auto& pair) {
      return std::binary_search(pairs.begin(), pairs.end(),
                                std::make_pair(pair.second, pair.first));
    });
  };
  // Every index in range, every size what the others say: a corrupt checkpoint is refused
  // here, never read out of bounds later.
  const auto within = [](const std::vector<int>& indices, std::uint64_t end, bool minus_one) {
    return std::all_of(indices.begin(), indices.end(), [&](int i) {
      return (minus_one && i == -1) || (i >= 0 && static_cast<std::uint64_t>(i) < end);
    });
  };
  const std::size_t n = aggregate_of.size();
  const std::uint64_t groups = top_dropped.size();
  const std::uint64_t factored_slots = three_level ? top_slots : slots;
  bool valid =
      updates >= 0 && aggregates <= n && within(aggregate_of, aggregates, true) &&
      offset.size() == n && centre.size() == aggregates && modes_from_raw.size() == aggregates &&
      raw_from_modes.size() == aggregates && dropped.size() == aggregates &&
      within(slots_by_row, slots, true) && slot_row.size() == slots &&
      slot_column.size() == slots && within(slot_row, aggregates, false) &&
      within(slot_column, aggregates, false) && diagonal_slot.size() == aggregates &&
      within(diagonal_slot, slots, false) && unknowns >= 0 &&
      static_cast<std::uint64_t>(unknowns) == kModes * (three_level ? groups : aggregates) &&
      outer.size() == static_cast<std::uint64_t>(unknowns) + 1 && !outer.empty() &&
      outer.front() == 0 && std::is_sorted(outer.begin(), outer.end()) &&
      static_cast<std::uint64_t>(outer.back()) == inner.size() && values.size() == inner.size() &&
      within(inner, static_cast<std::uint64_t>(unknowns), false) &&
      scalar_source.size() == inner.size() &&
      std::all_of(scalar_source.begin(), scalar_source.end(), [&](const auto& source) {
        return source.first >= 0 && static_cast<std::uint64_t>(source.first) < factored_slots &&
               source.second >= 0 && source.second < kModes * kModes;
      });
  if (valid && three_level) {
    valid = top_of.size() == aggregates && within(top_of, groups, false) &&
            top_slot.size() == slots && within(top_slot, top_slots, false) &&
            top_diagonal_slot.size() == groups && within(top_diagonal_slot, top_slots, false) &&
            top_map.size() == aggregates && own_inverse.size() == aggregates &&
            coarse_blocks.size() == slots && symmetric_rows(slot_row, slot_column);
  } else if (valid) {
    valid = top_of.empty() && top_slot.empty() && top_slots == 0;
  }
  if (!valid) {
    throw InputError("checkpoint: the coarse level of the two-level preconditioner is corrupt");
  }
  factored_ = true;
  updates_since_factor_ = updates;
  three_level_ = three_level;
  aggregated_ = std::move(looks[0]);
  seen_ = std::move(looks[1]);
  slots_by_row_ = std::move(slots_by_row);
  placed_pattern_.reset();  // coarse_slot_ is placed in the next matrix's storage when due
  coarse_slot_.clear();
  aggregate_of_ = std::move(aggregate_of);
  members_.assign(static_cast<std::size_t>(aggregates), {});
  collect_members();
  offset_ = std::move(offset);
  centre_ = std::move(centre);
  modes_from_raw_ = std::move(modes_from_raw);
  raw_from_modes_ = std::move(raw_from_modes);
  dropped_ = std::move(dropped);
  top_dropped_ = std::move(top_dropped);
  scalar_source_ = std::move(scalar_source);
  slot_row_ = std::move(slot_row);
  slot_column_ = std::move(slot_column);
  diagonal_slot_ = std::move(diagonal_slot);
  top_diagonal_slot_ = std::move(top_diagonal_slot);
  top_of_ = std::move(top_of);
  collect_top_members(three_level ? static_cast<std::size_t>(groups) : 0);
  top_slot_ = std::move(top_slot);
  top_map_ = std::move(top_map);
  own_inverse_ = std::move(own_inverse);
  if (three_level) {
    coarse_blocks_ = std::move(coarse_blocks);
  } else {
    coarse_blocks_.assign(static_cast<std::size_t>(slots), ModeMatrix::Zero());
  }
  collect_slot_rows();
  if (three_level) {
    prepare_cycle();
  }
  top_blocks_.assign(static_cast<std::size_t>(top_slots), ModeMatrix::Zero());
  coarse_motion_.assign(static_cast<std::size_t>(aggregates), Modes::Zero());
  const auto size = static_cast<Eigen::Index>(unknowns);
  scalar_.resize(size, size);
  scalar_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), scalar_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), scalar_.innerIndexPtr());
  std::copy(values.begin(), values.end(), scalar_.valuePtr());
  if (!members_.empty() && !factor_->factorize_positive_definite(scalar_)) {
    throw InputError(
        "checkpoint: the coarse matrix of the two-level preconditioner is not positive "
        "definite");
  }
}

bool AggregationCoarseSpace::update(const BlockSparseMatrix& matrix,
                                    std::span<const char> constrained,
                                    std::span<const Vec3> positions) {
  if (!positions.empty() && positions.size() != matrix.rows()) {
    throw std::invalid_argument("AggregationCoarseSpace::update: one position per matrix row");
  }
  const bool due = !factored_ || ++updates_since_factor_ >= refactor_every_ ||
                   matrix.rows() < aggregate_of_.size();
  if (!due) {
    // The factor of an earlier matrix is a good preconditioner still (the corotational
    // matrix changes with the elements' rotations, slowly; a cut changes it near the blade).
    if (!same_as(seen_, matrix, constrained)) {
      extend(matrix, constrained, positions);
      remember(seen_, matrix, constrained);
    }
    return true;
  }
  if (!same_as(aggregated_, matrix, constrained)) {
    aggregate(matrix, constrained);
    remember(aggregated_, matrix, constrained);
    remember(seen_, matrix, constrained);
  } else if (placed_pattern_ != matrix.pattern() || placed_version_ != matrix.pattern_version()) {
    place_slots(matrix);
  }
  updates_since_factor_ = 0;
  factored_ = true;
  shape_modes(positions);
  // P^T A P: each aggregate's coarse row from its members' rows (rows in parallel, each coarse
  // row summed in member order by one thread: deterministic). With P_v = R_v W_a, R_v =
  // [I, -[d_v]x]: the rows are summed in raw rigid coordinates, R_i^T A_ij R_j, and each coarse
  // block is turned into the modes' coordinates once, W_a^T (sum) W_b. R_i^T A_ij R_j is
  // [[A, -A [d_j]x], [[d_i]x A, -[d_i]x A [d_j]x]]: nine cross products, where the two dense
  // products of 6x3 matrices took about three times the arithmetic (the 384k-tet box: 27-29
  // ms a factorisation, BENCHMARKS.md).
  const auto values = matrix.values();
  const auto row_begin = matrix.row_begin();
  const auto row_end = matrix.row_end();
  std::fill(coarse_blocks_.begin(), coarse_blocks_.end(), ModeMatrix::Zero());
  parallel_for(0, members_.size(), 16, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      for (const VertexId v : members_[a]) {
        const auto i = static_cast<std::size_t>(v);
        const auto columns = matrix.row_columns(v);
        const Vec3& offset_i = offset_[i];
        for (std::size_t k = row_begin[i]; k < row_end[i]; ++k) {
          const int slot = coarse_slot_[k];
          if (slot >= 0) {
            add_rigid_block(values[k], offset_i,
                            offset_[static_cast<std::size_t>(columns[k - row_begin[i]])],
                            coarse_blocks_[static_cast<std::size_t>(slot)]);
          }
        }
      }
    }
  });
  parallel_for(0, coarse_blocks_.size(), 256, [&](std::size_t first, std::size_t last) {
    for (std::size_t s = first; s != last; ++s) {
      const auto a = static_cast<std::size_t>(slot_row_[s]);
      const auto b = static_cast<std::size_t>(slot_column_[s]);
      ModeMatrix& block = coarse_blocks_[s];
      block = raw_from_modes_[a].transpose() * block * raw_from_modes_[b];
      if (a == b) {
        fill_dropped(block, dropped_[a]);
      }
    }
  });
  const std::vector<ModeMatrix>* factored = &coarse_blocks_;
  if (three_level_) {
    parallel_for(0, own_inverse_.size(), kAggregateGrain, [&](std::size_t first, std::size_t last) {
      for (std::size_t a = first; a != last; ++a) {
        const ModeMatrix inverse =
            Eigen::LLT<ModeMatrix>(coarse_blocks_[static_cast<std::size_t>(diagonal_slot_[a])])
                .solve(ModeMatrix::Identity());
        own_inverse_[a] = 0.5 * (inverse + inverse.transpose());
      }
    });
    // The V-cycle is positive definite (CG needs it) when the damped smoother's largest
    // eigenvalue on P^T A P is below 2. Undamped it is 1.9 on the peers' box at 48k and 384k
    // tets: too close, so it is damped to kSmootherReach, which cost 4-8 % more iterations
    // than no damping there.
    prepare_cycle();
    const double reach = smoother_reach();
    if (reach > kSmootherReach) {
      const double damping = kSmootherReach / reach;
      for (ModeMatrix& inverse : own_inverse_) {
        inverse *= damping;
      }
    }
    std::fill(top_blocks_.begin(), top_blocks_.end(), ModeMatrix::Zero());
    for (std::size_t s = 0; s < coarse_blocks_.size(); ++s) {
      top_blocks_[static_cast<std::size_t>(top_slot_[s])].noalias() +=
          top_map_[static_cast<std::size_t>(slot_row_[s])].transpose() * coarse_blocks_[s] *
          top_map_[static_cast<std::size_t>(slot_column_[s])];
    }
    for (std::size_t t = 0; t < top_dropped_.size(); ++t) {
      fill_dropped(top_blocks_[static_cast<std::size_t>(top_diagonal_slot_[t])], top_dropped_[t]);
    }
    factored = &top_blocks_;
  }
  double* target = scalar_.valuePtr();
  for (std::size_t s = 0; s < scalar_source_.size(); ++s) {
    const auto [slot, entry] = scalar_source_[s];
    target[s] = (*factored)[static_cast<std::size_t>(slot)].data()[entry];
  }
  return members_.empty() || factor_->factorize_positive_definite(scalar_);
}

void AggregationCoarseSpace::add_correction(std::span<Vec3> z) const {
  // P e at vertex v: the aggregate's rigid motion t + w x d_v (P_v = [I, -[d_v]x] W_a), which
  // reads 24 bytes per vertex where P_v's rows would be 144. In vertex order, on the workers:
  // each vertex written once.
  parallel_for(0, aggregate_of_.size(), 4096, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      const int a = aggregate_of_[i];
      if (a >= 0) {
        const Modes& motion = coarse_motion_[static_cast<std::size_t>(a)];
        z[i] += motion.head<3>() + motion.tail<3>().cross(offset_[i]);
      }
    }
  });
}

double AggregationCoarseSpace::solve(std::span<const Vec3> residual) {
  const std::size_t aggregates = members_.size();
  if (aggregates == 0) {
    return 0.0;
  }
  // P^T r: P_v^T r_v = W_a^T (r_v, d_v x r_v), summed over each aggregate's members before
  // W_a^T. Every pass below is on the worker threads, each sum in a fixed order (the same bits
  // on any thread count): this solve runs beside the clusters' and, done on one thread, was a
  // CG iteration's critical path on 16 cores (BENCHMARKS.md). The members' sums go in vertex
  // order, chunk by chunk, into partial sums that each aggregate then adds in chunk order: read
  // member by member, the residual's and offsets' scattered loads took 10 % of a 384k-tet
  // frame, about 3x these two passes (BENCHMARKS.md).
  const std::size_t chunks = chunk_partial_first_.size() - 1;
  parallel_for(0, chunks, 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t c = first; c != last; ++c) {
      for (std::size_t p = chunk_partial_first_[c]; p != chunk_partial_first_[c + 1]; ++p) {
        partial_sums_[p].setZero();
      }
      const std::size_t end = std::min(partial_of_.size(), (c + 1) * kRestrictChunk);
      for (std::size_t v = c * kRestrictChunk; v < end; ++v) {
        const int p = partial_of_[v];
        if (p >= 0) {
          Modes& sum = partial_sums_[static_cast<std::size_t>(p)];
          sum.head<3>() += residual[v];
          sum.tail<3>() += offset_[v].cross(residual[v]);
        }
      }
    }
  });
  const auto restrict_to = [&](std::size_t a) {
    Modes raw = Modes::Zero();
    for (std::size_t k = aggregate_partial_first_[a]; k != aggregate_partial_first_[a + 1]; ++k) {
      raw += partial_sums_[static_cast<std::size_t>(aggregate_partials_[k])];
    }
    return raw;
  };
  if (!three_level_) {
    coarse_rhs_.resize(static_cast<Eigen::Index>(kModes * aggregates));
    parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
      for (std::size_t a = first; a != last; ++a) {
        coarse_rhs_.segment<kModes>(static_cast<Eigen::Index>(kModes * a)).noalias() =
            raw_from_modes_[a].transpose() * restrict_to(a);
      }
    });
    const Eigen::VectorXd solution = factor_->solve(coarse_rhs_);
    for (std::size_t a = 0; a < aggregates; ++a) {
      coarse_motion_[a].noalias() =
          raw_from_modes_[a] * solution.segment<kModes>(static_cast<Eigen::Index>(kModes * a));
    }
    return coarse_rhs_.dot(solution);
  }
  // Three levels: one symmetric V-cycle on P^T A P y = c, in the aggregates' modes: y = w L c
  // (each aggregate's own block), y += Q (c - P^T A P y) (the top level's exact solve), y += w L
  // (c - P^T A P y). Each pass below is by aggregate or by group, every sum in a fixed order.
  const std::size_t groups = top_first_.size() - 1;
  cycle_rhs_.resize(aggregates);
  cycle_solution_.resize(aggregates);
  cycle_residual_.resize(aggregates);
  parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      cycle_rhs_[a].noalias() = raw_from_modes_[a].transpose() * restrict_to(a);
      cycle_solution_[a].noalias() = own_inverse_[a] * cycle_rhs_[a];
    }
  });
  // By group: its aggregates' residuals after the smoothing, and their part of its right-hand
  // side (in aggregate order).
  coarse_rhs_.resize(static_cast<Eigen::Index>(kModes * groups));
  parallel_for(0, groups, kGroupGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t t = first; t != last; ++t) {
      Modes group_rhs = Modes::Zero();
      for (std::size_t k = top_first_[t]; k != top_first_[t + 1]; ++k) {
        const auto a = static_cast<std::size_t>(top_members_[k]);
        cycle_residual_[a] = coarse_residual(a, cycle_rhs_[a], cycle_solution_);
        group_rhs.noalias() += top_map_[a].transpose() * cycle_residual_[a];
      }
      coarse_rhs_.segment<kModes>(static_cast<Eigen::Index>(kModes * t)) = group_rhs;
    }
  });
  const Eigen::VectorXd top_solution = factor_->solve(coarse_rhs_);
  // y += Q e; then c - P^T A (y + Q e) = (c - P^T A y) - P^T A Q e, with (P^T A Q e)_a = sum
  // over its coupled groups t of K_at e_t; y += w L of that.
  own_part_.resize(aggregates);
  parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      cycle_solution_[a].noalias() +=
          top_map_[a] *
          top_solution.segment<kModes>(static_cast<Eigen::Index>(kModes * top_of_[a]));
      Modes left = cycle_residual_[a];
      for (std::size_t k = top_coupling_first_[a]; k != top_coupling_first_[a + 1]; ++k) {
        left.noalias() -= top_coupling_[k] * top_solution.segment<kModes>(static_cast<Eigen::Index>(
                                                 kModes * top_coupling_group_[k]));
      }
      cycle_solution_[a].noalias() += own_inverse_[a] * left;
      coarse_motion_[a].noalias() = raw_from_modes_[a] * cycle_solution_[a];
      own_part_[a] = cycle_rhs_[a].dot(cycle_solution_[a]);
    }
  });
  // r.z = (P^T r).y, in the aggregates' order.
  double sum = 0.0;
  for (const double part : own_part_) {
    sum += part;
  }
  return sum;
}

AggregationCoarseSpace::Modes AggregationCoarseSpace::coarse_residual(
    std::size_t aggregate, const Modes& c, const std::vector<Modes>& y) const {
  // Column by column, so each column's six floats widen together and the sum stays in
  // registers (as a whole-block product this was scalar, a quarter of a fine product's time).
  Modes residual = c;
  for (std::size_t s = slot_first_[aggregate]; s != slot_first_[aggregate + 1]; ++s) {
    const Eigen::Matrix<float, kModes, kModes>& block = single_blocks_[s];
    const Modes& motion = y[static_cast<std::size_t>(slot_column_[s])];
    for (int j = 0; j < kModes; ++j) {
      residual.noalias() -= block.col(j).cast<double>() * motion(j);
    }
  }
  return residual;
}

double AggregationCoarseSpace::smoother_reach() const {
  // Power iteration on L (P^T A P) from a fixed rough start (a smooth one holds little of the
  // top eigenvector; minstd_rand's sequence is the same everywhere, so is the damping): twelve
  // steps put it within a few per cent of the largest eigenvalue on the peers' box, which the
  // margin below 2 in kSmootherReach covers.
  const std::size_t aggregates = members_.size();
  std::vector<Modes> x(aggregates);
  std::minstd_rand sequence(7);
  for (Modes& entry : x) {
    for (int m = 0; m < kModes; ++m) {
      entry(m) = 2.0 * static_cast<double>(sequence() - std::minstd_rand::min()) /
                     static_cast<double>(std::minstd_rand::max() - std::minstd_rand::min()) -
                 1.0;
    }
  }
  std::vector<Modes> product(aggregates);
  double estimate = 0.0;
  for (int step = 0; step < 12; ++step) {
    parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
      for (std::size_t a = first; a != last; ++a) {
        product[a] = -(own_inverse_[a] * coarse_residual(a, Modes::Zero(), x));
      }
    });
    double before = 0.0;
    double after = 0.0;
    for (std::size_t a = 0; a < aggregates; ++a) {
      before += x[a].squaredNorm();
      after += product[a].squaredNorm();
    }
    if (before <= 0.0 || after <= 0.0) {
      return estimate;
    }
    estimate = std::sqrt(after / before);
    const double scale = 1.0 / std::sqrt(after);
    for (std::size_t a = 0; a < aggregates; ++a) {
      x[a] = scale * product[a];
    }
  }
  return estimate;
}

void AggregationCoarseSpace::prepare_cycle() {
  // The V-cycle is symmetric only if both its products use one symmetric matrix: block (b, a)
  // is taken as the transpose of block (a, b) for a < b (the sums behind the two differ in
  // their last bits, and rounding to float can make that 1e-7), and the top correction's
  // product below uses these rounded blocks too.
  const std::size_t aggregates = members_.size();
  single_blocks_.resize(coarse_blocks_.size());
  parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      for (std::size_t s = slot_first_[a]; s != slot_first_[a + 1]; ++s) {
        const auto b = static_cast<std::size_t>(slot_column_[s]);
        if (b == a) {
          single_blocks_[s] =
              (0.5 * (coarse_blocks_[s] + coarse_blocks_[s].transpose())).cast<float>();
        } else if (a < b) {
          single_blocks_[s] = coarse_blocks_[s].cast<float>();
        } else {
          const auto row_begin = slot_column_.begin() + static_cast<std::ptrdiff_t>(slot_first_[b]);
          const auto row_end =
              slot_column_.begin() + static_cast<std::ptrdiff_t>(slot_first_[b + 1]);
          const auto mirror = std::lower_bound(row_begin, row_end, static_cast<int>(a));
          INCISE_ASSERT(mirror != row_end && *mirror == static_cast<int>(a),
                        "coarse pattern not symmetric");
          single_blocks_[s] =
              coarse_blocks_[static_cast<std::size_t>(mirror - slot_column_.begin())]
                  .transpose()
                  .cast<float>();
        }
      }
    }
  });
  // Each aggregate's coupled groups in the order its slots first reach them.
  top_coupling_first_.assign(1, 0);
  top_coupling_group_.clear();
  std::vector<int> place(top_first_.size(), -1);
  std::vector<std::size_t> slot_place(coarse_blocks_.size());
  for (std::size_t a = 0; a < aggregates; ++a) {
    const std::size_t row_first = top_coupling_group_.size();
    for (std::size_t s = slot_first_[a]; s != slot_first_[a + 1]; ++s) {
      const int t = top_of_[static_cast<std::size_t>(slot_column_[s])];
      if (place[static_cast<std::size_t>(t)] < static_cast<int>(row_first)) {
        place[static_cast<std::size_t>(t)] = static_cast<int>(top_coupling_group_.size());
        top_coupling_group_.push_back(t);
      }
      slot_place[s] = static_cast<std::size_t>(place[static_cast<std::size_t>(t)]);
    }
    top_coupling_first_.push_back(top_coupling_group_.size());
  }
  top_coupling_.resize(top_coupling_group_.size());
  parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      for (std::size_t k = top_coupling_first_[a]; k != top_coupling_first_[a + 1]; ++k) {
        top_coupling_[k].setZero();
      }
      for (std::size_t s = slot_first_[a]; s != slot_first_[a + 1]; ++s) {
        top_coupling_[slot_place[s]].noalias() +=
            single_blocks_[s].cast<double>() * top_map_[static_cast<std::size_t>(slot_column_[s])];
      }
    }
  });
}

void AggregationCoarseSpace::collect_slot_rows() {
  key_offsets(slot_row_, members_.size(), slot_first_);
}

}  // namespace incise
