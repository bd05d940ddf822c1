#include "incise/solve/aggregation_coarse_space.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "coarse_cycle.hpp"
#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"

namespace incise {

AggregationCoarseSpace::AggregationCoarseSpace()
    : cycle_(std::make_unique<coarse::CoarseCycle>()) {}

AggregationCoarseSpace::~AggregationCoarseSpace() = default;

std::size_t AggregationCoarseSpace::group_levels() const {
  return cycle_->group_levels();
}

std::vector<std::size_t> AggregationCoarseSpace::level_sizes() const {
  return cycle_->level_sizes();
}

std::span<const int> AggregationCoarseSpace::group_of(std::size_t level) const {
  INCISE_ASSERT(level < cycle_->group_levels(), "a coarse level below the top");
  return cycle_->group_of(level);
}

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

using coarse::fill_dropped;
using coarse::Graph;
using coarse::greedy_aggregates;
using coarse::group_by_key;
using coarse::kModes;
using coarse::ModeMatrix;
using coarse::Modes;
using coarse::orthonormal_modes;
using coarse::OrthonormalModes;
using VertexModes = AggregationCoarseSpace::VertexModes;
/// Per task in the coarse solve's passes: aggregates (some 1,500 vertices each).
constexpr std::size_t kAggregateGrain = 64;

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
  // A large coarse system costs more to solve than a product at every iteration (7,600
  // unknowns on the 384k-tet box: 4 ms against 3.5): above exact_limit_ unknowns it is solved
  // by a V-cycle over groups of aggregates (coarse_cycle.hpp).
  cycle_->build(aggregates, slot_row_, slot_column_, exact_limit_);
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
  const std::size_t chunks = (n + kRestrictionChunk - 1) / kRestrictionChunk;
  partial_of_.resize(n);
  chunk_partial_first_.assign(chunks + 1, 0);
  std::vector<int> partial_aggregate;
  std::vector<std::size_t> last_chunk(aggregates, chunks);
  std::vector<int> last_partial(aggregates, -1);
  for (std::size_t c = 0; c < chunks; ++c) {
    for (std::size_t i = c * kRestrictionChunk; i < std::min(n, (c + 1) * kRestrictionChunk); ++i) {
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
  out.values(slot_row_);
  out.values(slot_column_);
  // P^T A P as last factorised: the levels above, their smoothers and the factor are made
  // again from it, in the same order, so a resumed run solves exactly as it would have.
  out.values(cycle_->aggregate_blocks());
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
  auto slot_row = in.values<int>("coarse slot rows");
  auto slot_column = in.values<int>("coarse slot columns");
  auto coarse_blocks = in.values<ModeMatrix>("coarse blocks");

  // The levels above find block (b, a) beside (a, b): slots row by row, each row's columns
  // increasing, each aggregate's own among them, and the pattern symmetric.
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
                                std::make_pair(pair.second, pair.first)) &&
             std::binary_search(pairs.begin(), pairs.end(), std::make_pair(pair.first, pair.first));
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
  const std::uint64_t slots = slot_row.size();
  const bool valid =
      updates >= 0 && aggregates <= n && within(aggregate_of, aggregates, true) &&
      offset.size() == n && centre.size() == aggregates && modes_from_raw.size() == aggregates &&
      raw_from_modes.size() == aggregates && dropped.size() == aggregates &&
      within(slots_by_row, slots, true) && slot_column.size() == slots &&
      within(slot_row, aggregates, false) && within(slot_column, aggregates, false) &&
      coarse_blocks.size() == slots && symmetric_rows(slot_row, slot_column) &&
      (aggregates == 0 ||
       (!slot_row.empty() && static_cast<std::uint64_t>(slot_row.back()) + 1 == aggregates));
  if (!valid) {
    throw InputError("checkpoint: the coarse level of the two-level preconditioner is corrupt");
  }
  factored_ = true;
  updates_since_factor_ = updates;
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
  slot_row_ = std::move(slot_row);
  slot_column_ = std::move(slot_column);
  cycle_->build(members_.size(), slot_row_, slot_column_, exact_limit_);
  cycle_->aggregate_blocks() = std::move(coarse_blocks);
  coarse_motion_.assign(static_cast<std::size_t>(aggregates), Modes::Zero());
  if (!members_.empty() && !cycle_->assemble(centre_, modes_from_raw_)) {
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
  std::fill(cycle_->aggregate_blocks().begin(), cycle_->aggregate_blocks().end(),
            ModeMatrix::Zero());
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
                            cycle_->aggregate_blocks()[static_cast<std::size_t>(slot)]);
          }
        }
      }
    }
  });
  parallel_for(0, cycle_->aggregate_blocks().size(), 256, [&](std::size_t first, std::size_t last) {
    for (std::size_t s = first; s != last; ++s) {
      const auto a = static_cast<std::size_t>(slot_row_[s]);
      const auto b = static_cast<std::size_t>(slot_column_[s]);
      ModeMatrix& block = cycle_->aggregate_blocks()[s];
      block = raw_from_modes_[a].transpose() * block * raw_from_modes_[b];
      if (a == b) {
        fill_dropped(block, dropped_[a]);
      }
    }
  });
  return members_.empty() || cycle_->assemble(centre_, modes_from_raw_);
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

void AggregationCoarseSpace::restrict_chunk(std::size_t chunk, std::span<const Vec3> residual) {
  if (chunk + 1 >= chunk_partial_first_.size()) {
    return;  // past the vertices aggregated (none, or rows added since)
  }
  for (std::size_t p = chunk_partial_first_[chunk]; p != chunk_partial_first_[chunk + 1]; ++p) {
    partial_sums_[p].setZero();
  }
  const std::size_t end = std::min(partial_of_.size(), (chunk + 1) * kRestrictionChunk);
  for (std::size_t v = chunk * kRestrictionChunk; v < end; ++v) {
    const int p = partial_of_[v];
    if (p >= 0) {
      Modes& sum = partial_sums_[static_cast<std::size_t>(p)];
      sum.head<3>() += residual[v];
      sum.tail<3>() += offset_[v].cross(residual[v]);
    }
  }
}

double AggregationCoarseSpace::solve(std::span<const Vec3> residual) {
  if (members_.empty()) {
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
      restrict_chunk(c, residual);
    }
  });
  return solve_restricted();
}

double AggregationCoarseSpace::solve_restricted() {
  const std::size_t aggregates = members_.size();
  if (aggregates == 0) {
    return 0.0;
  }
  const auto restrict_to = [&](std::size_t a) {
    Modes raw = Modes::Zero();
    for (std::size_t k = aggregate_partial_first_[a]; k != aggregate_partial_first_[a + 1]; ++k) {
      raw += partial_sums_[static_cast<std::size_t>(aggregate_partials_[k])];
    }
    return raw;
  };
  cycle_rhs_.resize(aggregates);
  cycle_solution_.resize(aggregates);
  parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
      cycle_rhs_[a].noalias() = raw_from_modes_[a].transpose() * restrict_to(a);
    }
  });
  cycle_->solve(cycle_rhs_, cycle_solution_);
  own_part_.resize(aggregates);
  parallel_for(0, aggregates, kAggregateGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t a = first; a != last; ++a) {
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

}  // namespace incise
