#include "incise/xfem/xfem_cutter.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/predicates.hpp"

namespace incise {
namespace {

/// A corner's side: unknown, a (the swept surface's negative side) or b (positive).
enum Side : std::int8_t { kUnknown = 0, kSideA = -1, kSideB = 1 };

}  // namespace

XfemCutter::XfemCutter(TetMesh& mesh, XfemCutterOptions options) : mesh_(&mesh), options_(options) {
  if (!(options_.min_fraction >= 0.0 && options_.min_fraction < 0.5)) {
    throw InputError("xfem cutter: min_fraction must lie in [0, 0.5)");
  }
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    if (mesh.material_fraction(static_cast<TetId>(t)) != 1.0) {
      throw InputError("xfem cutter: tetrahedron " + std::to_string(t) +
                       " is already a virtual element (material fraction below 1)");
    }
  }
  rest_tets_.assign(mesh.tets().begin(), mesh.tets().end());
  rest_vertices_ = mesh.vertex_count();
  state_.assign(rest_tets_.size(), TetState::kWhole);
  cuts_.resize(rest_tets_.size());
  second_element_.assign(rest_tets_.size(), kInvalidId);
  reached_at_.assign(rest_tets_.size(), {0.0, 0.0});
  touched_.assign(rest_vertices_, 0);
  copy_of_.assign(rest_vertices_, kInvalidId);
  if (options_.quad_length <= 0.0) {
    double total = 0.0;
    for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
      const auto& [a, b] = mesh.edge(static_cast<EdgeId>(e));
      total += (mesh.rest_position(a) - mesh.rest_position(b)).norm();
    }
    options_.quad_length =
        mesh.edge_count() > 0 ? total / static_cast<double>(mesh.edge_count()) : 1.0;
  }
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    std::array<VertexId, 3> key = face.vertices;
    std::sort(key.begin(), key.end());
    rest_boundary_.insert(key);
  }
  grid_ = std::make_unique<TetGrid>(mesh);
}

bool XfemCutter::opened(const Triangle& face) const {
  std::array<VertexId, 3> key{};
  for (std::size_t k = 0; k < 3; ++k) {
    const VertexOrigin& origin = mesh_->vertex_origin(face[k]);
    key[k] = static_cast<std::size_t>(face[k]) >= rest_vertices_ ? origin.parents[0] : face[k];
  }
  std::sort(key.begin(), key.end());
  return !rest_boundary_.contains(key);
}

XfemCutter::~XfemCutter() = default;

TetId XfemCutter::rest_tet_of(TetId element) const {
  const auto index = static_cast<std::size_t>(element);
  return index < rest_tets_.size() ? element : rest_of_appended_[index - rest_tets_.size()];
}

void XfemCutter::start(const BladePose& pose) {
  last_ = pose;
  started_ = true;
  continues_ = false;
}

const XfemCutter::EdgeRecord* XfemCutter::record(VertexId a, VertexId b) const {
  const auto found = edges_.find(edge_key(a, b));
  return found == edges_.end() ? nullptr : &found->second;
}

void XfemCutter::test_quad(const BladePose& from, const BladePose& to,
                           std::vector<TetId>& changed) {
  const auto triangles = swept_triangles(from, to);
  if (triangles.empty()) {
    return;
  }
  Vec3 low = from.tip.cwiseMin(from.base).cwiseMin(to.tip).cwiseMin(to.base);
  Vec3 high = from.tip.cwiseMax(from.base).cwiseMax(to.tip).cwiseMax(to.base);
  std::vector<TetId> near;
  grid_->query(low, high, near);
  // A quad that continues the stroke shares its start line with the previous quad's end line,
  // which already counted what crosses it: the start line is open, the end line closed, so a
  // crossing exactly on the line between two quads counts once. Decided exactly: the edge
  // meets the start segment.
  const bool open_start = continues_;
  continues_ = true;
  // An edge shared by several tetrahedra, or through the quad's diagonal, counts once.
  std::unordered_set<std::uint64_t> tested;
  for (TetId t : near) {
    const auto index = static_cast<std::size_t>(t);
    if (index >= rest_tets_.size() || state_[index] == TetState::kSplit) {
      continue;
    }
    const Tet& tet = rest_tets_[index];
    bool any = false;
    for (const auto& edge : tet_local::kEdges) {
      const VertexId i = tet[static_cast<std::size_t>(edge[0])];
      const VertexId j = tet[static_cast<std::size_t>(edge[1])];
      const std::uint64_t key = edge_key(i, j);
      if (!tested.insert(key).second) {
        any = any || edges_.contains(key);
        continue;
      }
      const Vec3& xi = mesh_->rest_position(i);
      const Vec3& xj = mesh_->rest_position(j);
      if (open_start && segments_intersect(xi, xj, from.tip, from.base)) {
        any = any || edges_.contains(key);
        continue;
      }
      for (const auto& triangle : triangles) {
        if (!segment_intersects_triangle(xi, xj, triangle[0], triangle[1], triangle[2])) {
          continue;
        }
        any = record_crossing(i, j, triangle) || any;
        break;
      }
    }
    if (any) {
      changed.push_back(t);
    }
  }
}

bool XfemCutter::record_crossing(VertexId i, VertexId j, const std::array<Vec3, 3>& triangle) {
  const Vec3& xi = mesh_->rest_position(i);
  const Vec3& xj = mesh_->rest_position(j);
  const Sign si = orient3d(triangle[0], triangle[1], triangle[2], xi);
  const Sign sj = orient3d(triangle[0], triangle[1], triangle[2], xj);
  const std::uint64_t key = edge_key(i, j);
  // A split tetrahedron's edge keeps its crossings (its neighbours must cut their shared faces
  // as it did); a touch at an end still tells neighbours that corner lies on the surface.
  if (frozen_.contains(key)) {
    const EdgeRecord* kept = record(i, j);
    if ((kept != nullptr && kept->crossings % 2 == 1) || (si != Sign::kZero && sj != Sign::kZero)) {
      return true;
    }
  }
  EdgeRecord& rec = edges_[key];
  const bool i_low = i < j;
  std::int8_t& side_i = i_low ? rec.side_low : rec.side_high;
  std::int8_t& side_j = i_low ? rec.side_high : rec.side_low;
  // orient3d > 0: on the side the triangle's normal points to: side b.
  const auto side_of = [](Sign s) { return s == Sign::kPositive ? kSideB : kSideA; };
  if (si == Sign::kZero || sj == Sign::kZero) {
    // The surface passes exactly through an end (or holds the whole edge): that end lies on
    // side a; the other end's side is its orientation.
    if (si == Sign::kZero) {
      touched_[static_cast<std::size_t>(i)] = 1;
      side_i = kSideA;
      if (sj != Sign::kZero) {
        side_j = side_of(sj);
      }
    }
    if (sj == Sign::kZero) {
      touched_[static_cast<std::size_t>(j)] = 1;
      side_j = kSideA;
      if (si != Sign::kZero) {
        side_i = side_of(si);
      }
    }
    return true;
  }
  const Vec3 normal = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]);
  const double hi = normal.dot(xi - triangle[0]);
  const double hj = normal.dot(xj - triangle[0]);
  const double from_i = std::clamp(hi / (hi - hj), 1e-9, 1.0 - 1e-9);
  ++rec.crossings;
  side_i = side_of(si);
  side_j = side_of(sj);
  rec.at = i_low ? from_i : 1.0 - from_i;
  return true;
}

std::optional<ElementCut> XfemCutter::resolve(TetId rest_tet, bool& reached) const {
  const Tet& tet = rest_tets_[static_cast<std::size_t>(rest_tet)];
  std::array<std::int8_t, 4> side{kUnknown, kUnknown, kUnknown, kUnknown};
  reached = false;
  bool conflict = false;
  const auto assign = [&](std::size_t corner, std::int8_t value) {
    if (value == kUnknown) {
      return;
    }
    conflict = conflict || (side[corner] != kUnknown && side[corner] != value);
    side[corner] = value;
  };
  std::array<const EdgeRecord*, 6> records{};
  for (std::size_t k = 0; k < 6; ++k) {
    const auto i = static_cast<std::size_t>(tet_local::kEdges[k][0]);
    const auto j = static_cast<std::size_t>(tet_local::kEdges[k][1]);
    records[k] = record(tet[i], tet[j]);
    if (records[k] == nullptr) {
      continue;
    }
    const EdgeRecord& rec = *records[k];
    const bool odd = rec.crossings % 2 == 1;
    const bool touch_i = touched_[static_cast<std::size_t>(tet[i])] != 0;
    const bool touch_j = touched_[static_cast<std::size_t>(tet[j])] != 0;
    if (odd || touch_i || touch_j) {
      reached = true;
      const bool i_low = tet[i] < tet[j];
      assign(i, i_low ? rec.side_low : rec.side_high);
      assign(j, i_low ? rec.side_high : rec.side_low);
    }
  }
  for (std::size_t c = 0; c < 4; ++c) {
    if (touched_[static_cast<std::size_t>(tet[c])] != 0) {
      assign(c, kSideA);
    }
  }
  if (!reached || conflict) {
    return std::nullopt;
  }
  // Corners no record placed are on the side of a corner they share an uncrossed edge with.
  for (int pass = 0; pass < 3; ++pass) {
    for (std::size_t k = 0; k < 6; ++k) {
      const auto i = static_cast<std::size_t>(tet_local::kEdges[k][0]);
      const auto j = static_cast<std::size_t>(tet_local::kEdges[k][1]);
      if (records[k] != nullptr && records[k]->crossings % 2 == 1) {
        continue;
      }
      if (side[i] == kUnknown && side[j] != kUnknown) {
        side[i] = side[j];
      } else if (side[j] == kUnknown && side[i] != kUnknown) {
        side[j] = side[i];
      }
    }
  }
  ElementCut cut;
  bool any_b = false;
  bool any_a = false;
  for (std::size_t c = 0; c < 4; ++c) {
    if (side[c] == kUnknown) {
      return std::nullopt;
    }
    cut.on_b[c] = side[c] == kSideB;
    any_b = any_b || cut.on_b[c];
    any_a = any_a || !cut.on_b[c];
  }
  if (!any_a || !any_b) {
    // Every corner on one side (the surface at most touches it): not part of the front.
    bool odd_edge = false;
    for (const EdgeRecord* rec : records) {
      odd_edge = odd_edge || (rec != nullptr && rec->crossings % 2 == 1);
    }
    reached = odd_edge;
    return std::nullopt;
  }
  // Every edge between the sides must have been crossed (an odd number of times) or touched at
  // its side-a end; every edge within a side must not be crossed.
  for (std::size_t k = 0; k < 6; ++k) {
    const auto i = static_cast<std::size_t>(tet_local::kEdges[k][0]);
    const auto j = static_cast<std::size_t>(tet_local::kEdges[k][1]);
    const bool odd = records[k] != nullptr && records[k]->crossings % 2 == 1;
    if (cut.on_b[i] == cut.on_b[j]) {
      if (odd) {
        return std::nullopt;
      }
      continue;
    }
    const std::size_t a_end = cut.on_b[i] ? j : i;
    if (odd) {
      const double from_low = records[k]->at;
      cut.crossing[k] = tet[i] < tet[j] ? from_low : 1.0 - from_low;
    } else if (touched_[static_cast<std::size_t>(tet[a_end])] != 0) {
      cut.crossing[k] = a_end == i ? 1e-9 : 1.0 - 1e-9;
    } else {
      return std::nullopt;
    }
  }
  return cut;
}

std::vector<std::uint8_t> XfemCutter::tied_now() const {
  std::vector<std::uint8_t> tied(rest_vertices_, 0);
  for (TetId t : front_) {
    if (state_[static_cast<std::size_t>(t)] != TetState::kFront) {
      continue;
    }
    const Tet& tet = rest_tets_[static_cast<std::size_t>(t)];
    for (const auto& edge : tet_local::kEdges) {
      const VertexId i = tet[static_cast<std::size_t>(edge[0])];
      const VertexId j = tet[static_cast<std::size_t>(edge[1])];
      const EdgeRecord* rec = record(i, j);
      if (rec == nullptr) {
        continue;
      }
      if (rec->crossings % 2 == 1) {
        tied[static_cast<std::size_t>(i)] = 1;
        tied[static_cast<std::size_t>(j)] = 1;
      }
    }
    for (VertexId v : tet) {
      if (touched_[static_cast<std::size_t>(v)] != 0) {
        tied[static_cast<std::size_t>(v)] = 1;
      }
    }
  }
  return tied;
}

void XfemCutter::release_ties(const std::vector<std::uint8_t>& tied) {
  std::vector<VertexId> released;
  for (const auto& [vertex, users] : tied_users_) {
    if (tied[static_cast<std::size_t>(vertex)] == 0) {
      released.push_back(vertex);
    }
  }
  std::sort(released.begin(), released.end());  // the same order on every run
  for (VertexId v : released) {
    const auto users = tied_users_.at(v);
    tied_users_.erase(v);
    INCISE_ASSERT(copy_of_[static_cast<std::size_t>(v)] == kInvalidId, "a tied vertex has no copy");
    copy_of_[static_cast<std::size_t>(v)] = mesh_->duplicate_vertex(v, users);
    ++stats_.copies;
  }
}

bool XfemCutter::split(TetId rest_tet, const ElementCut& cut,
                       const std::vector<std::uint8_t>& tied) {
  const auto index = static_cast<std::size_t>(rest_tet);
  const Tet& real = rest_tets_[index];
  int tied_corners = 0;
  bool a_empty = true;  // side a holds only corners on the surface: no material there
  for (std::size_t c = 0; c < 4; ++c) {
    const auto v = static_cast<std::size_t>(real[c]);
    tied_corners += copy_of_[v] == kInvalidId && tied[v] != 0 ? 1 : 0;
    a_empty = a_empty && (cut.on_b[c] || touched_[v] != 0);
  }
  if (tied_corners >= 3 && !a_empty) {
    return false;  // the two elements would share a face: wait for the front to move on
  }
  const std::array<Vec3, 4> corners = rest_corners(*mesh_, rest_tet);  // still whole here
  double fraction_a = 0.0;
  if (!a_empty) {
    fraction_a = side_volumes(corners, cut).fraction_a();
    if (fraction_a < options_.min_fraction || 1.0 - fraction_a < options_.min_fraction) {
      fraction_a = std::clamp(fraction_a, options_.min_fraction, 1.0 - options_.min_fraction);
      stats_.fractions_raised += 2;
    }
  }
  std::vector<VertexId> tied_here;
  Tet ghosts{};
  for (std::size_t c = 0; c < 4; ++c) {
    const VertexId v = real[c];
    const auto vi = static_cast<std::size_t>(v);
    // Corners across the cut from this one: the side whose element takes its ghost.
    std::array<VertexId, 4> far{};
    std::size_t far_count = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      if (cut.on_b[k] != cut.on_b[c]) {
        far[far_count++] = real[k];
      }
    }
    const bool ghost_used = !a_empty || !cut.on_b[c];  // a lone element b has side a's ghosts
    if (copy_of_[vi] != kInvalidId && ghost_used && far_count > 0) {
      // An earlier cut's copy is this side's ghost only when it is joined to this side's
      // corners. A blade that crosses its own cut can meet a copy that went with a piece the
      // first cut took off (soak finding 501075): as a ghost here it would tie that piece back
      // to the body. Such a side gets a copy of its own, which later splits of it share.
      VertexId joined = copy_joined_to(v, std::span(far.data(), far_count));
      if (joined == kInvalidId) {
        joined = mesh_->duplicate_vertex(v, {});
        more_copies_[v].push_back(joined);
        ++stats_.copies;
      }
      ghosts[c] = joined;
    } else if (copy_of_[vi] != kInvalidId) {
      ghosts[c] = copy_of_[vi];
    } else if (tied[vi] != 0) {
      ghosts[c] = v;
      tied_here.push_back(v);
    } else {
      copy_of_[vi] = mesh_->duplicate_vertex(v, {});
      ++stats_.copies;
      ghosts[c] = copy_of_[vi];
    }
  }
  const VirtualElements elements = virtual_elements(real, cut, ghosts);
  std::vector<TetId> ids;
  if (a_empty) {
    ids = mesh_->replace_tet(rest_tet, std::span(&elements.b, 1));
  } else {
    const std::array<Tet, 2> children{elements.a, elements.b};
    ids = mesh_->replace_tet(rest_tet, children);
    mesh_->set_material_fraction(ids[0], fraction_a);
    mesh_->set_material_fraction(ids[1], 1.0 - fraction_a);
    second_element_[index] = ids[1];
    INCISE_ASSERT(static_cast<std::size_t>(ids[1]) == rest_tets_.size() + rest_of_appended_.size(),
                  "virtual elements are appended in order");
    rest_of_appended_.push_back(rest_tet);
    stats_.min_fraction = std::min({stats_.min_fraction, fraction_a, 1.0 - fraction_a});
  }
  // Elements that use a tied vertex in place of its copy move to the copy once it is made:
  // element a uses copies for its side-b corners, element b for its side-a corners.
  for (VertexId v : tied_here) {
    const auto corner =
        static_cast<std::size_t>(std::find(real.begin(), real.end(), v) - real.begin());
    auto& users = tied_users_[v];
    if (a_empty) {
      if (!cut.on_b[corner]) {
        users.push_back(ids[0]);
      }
    } else {
      users.push_back(cut.on_b[corner] ? ids[0] : ids[1]);
    }
  }
  cuts_[index] = cut;
  state_[index] = TetState::kSplit;
  freeze_edges(real);
  ++stats_.elements_split;
  return true;
}

VertexId XfemCutter::copy_joined_to(VertexId vertex, std::span<const VertexId> far_corners) const {
  // A copy is joined to a corner when the corner lies within a few vertices of it through the
  // elements as they are now: the far side of one cut is the copy's own neighbourhood, while
  // a piece a cut took off has no element in common with the body at all.
  constexpr int kRings = 3;
  std::vector<VertexId> candidates{copy_of_[static_cast<std::size_t>(vertex)]};
  if (const auto more = more_copies_.find(vertex); more != more_copies_.end()) {
    candidates.insert(candidates.end(), more->second.begin(), more->second.end());
  }
  std::unordered_set<VertexId> seen;
  std::vector<VertexId> frontier;
  std::vector<VertexId> next;
  for (const VertexId copy : candidates) {
    seen = {copy};
    frontier = {copy};
    for (int ring = 0; ring < kRings && !frontier.empty(); ++ring) {
      next.clear();
      for (const VertexId u : frontier) {
        for (const TetId t : mesh_->vertex_tets(u)) {
          for (const VertexId w : mesh_->tet(t)) {
            if (std::find(far_corners.begin(), far_corners.end(), w) != far_corners.end()) {
              return copy;
            }
            if (seen.insert(w).second) {
              next.push_back(w);
            }
          }
        }
      }
      std::swap(frontier, next);
    }
  }
  return kInvalidId;
}

void XfemCutter::freeze_edges(const Tet& rest_tet) {
  for (const auto& edge : tet_local::kEdges) {
    frozen_.insert(edge_key(rest_tet[static_cast<std::size_t>(edge[0])],
                            rest_tet[static_cast<std::size_t>(edge[1])]));
  }
}

void XfemCutter::sweep(const BladePose& from, const BladePose& to, std::vector<TetId>& changed) {
  // The collision quad, re-formed every quad_length of travel (of the faster blade end).
  // At most kMaxQuads a move: a pose far off (a device's glitch, a path's typo) would ask for
  // more quads than an int counts, and time without end; beyond the cap the quads are longer.
  constexpr double kMaxQuads = 4096.0;
  const double travel = std::max((to.tip - from.tip).norm(), (to.base - from.base).norm());
  const double wanted = std::ceil(travel / options_.quad_length);
  const int pieces = wanted > 1.0 ? static_cast<int>(std::min(wanted, kMaxQuads)) : 1;
  BladePose previous = from;
  for (int k = 1; k <= pieces; ++k) {
    const double w = static_cast<double>(k) / pieces;
    const BladePose next{(1.0 - w) * from.time + w * to.time, (1.0 - w) * from.tip + w * to.tip,
                         (1.0 - w) * from.base + w * to.base};
    test_quad(previous, next, changed);
    ++stats_.quads;
    previous = next;
  }
}

void XfemCutter::move_to(const BladePose& pose) {
  INCISE_ASSERT(started_, "start() before move_to()");
  auto start = Clock::now();
  std::vector<TetId> changed;
  sweep(last_, pose, changed);
  travel_ += (0.5 * (pose.tip + pose.base) - 0.5 * (last_.tip + last_.base)).norm();
  last_ = pose;
  ++stats_.moves;
  // Whole tetrahedra the records now cross completely, and the front.
  for (TetId t : front_) {
    changed.push_back(t);  // waiting ones are tried again; front ones may have completed
  }
  std::sort(changed.begin(), changed.end());
  changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
  std::vector<std::pair<TetId, ElementCut>> ready;
  front_.clear();
  for (TetId t : changed) {
    auto& state = state_[static_cast<std::size_t>(t)];
    if (state == TetState::kSplit) {
      continue;
    }
    bool reached = false;
    auto cut = resolve(t, reached);
    if ((cut || reached) && state == TetState::kWhole) {
      reached_at_[static_cast<std::size_t>(t)] = {pose.time, travel_};
    }
    if (cut) {
      ready.emplace_back(t, *cut);
      state = TetState::kWaiting;
      front_.push_back(t);
    } else if (reached) {
      state = TetState::kFront;
      front_.push_back(t);
    } else {
      state = TetState::kWhole;
    }
  }
  stats_.cd_seconds = seconds_since(start);

  start = Clock::now();
  const std::vector<std::uint8_t> tied = tied_now();
  release_ties(tied);
  for (const auto& [t, cut] : ready) {
    if (split(t, cut, tied)) {
      // How long the physics waited behind the blade: from the move that first reached the
      // tetrahedron to the one that split it (the seed's Fig. 12 delay).
      const auto& [time, travel] = reached_at_[static_cast<std::size_t>(t)];
      stats_.delay_sum += pose.time - time;
      stats_.delay_max = std::max(stats_.delay_max, pose.time - time);
      stats_.delay_travel_sum += travel_ - travel;
      stats_.delay_travel_max = std::max(stats_.delay_travel_max, travel_ - travel);
    }
  }
  std::erase_if(front_,
                [&](TetId t) { return state_[static_cast<std::size_t>(t)] == TetState::kSplit; });
  stats_.front_tets = 0;
  stats_.waiting_tets = 0;
  for (TetId t : front_) {
    (state_[static_cast<std::size_t>(t)] == TetState::kFront ? stats_.front_tets
                                                             : stats_.waiting_tets) += 1;
  }
  stats_.tied_vertices = tied_users_.size();
  stats_.tremor_edges = 0;
  for (const auto& [key, rec] : edges_) {
    stats_.tremor_edges += rec.crossings > 0 && rec.crossings % 2 == 0 ? 1 : 0;
  }
  stats_.gc_seconds = seconds_since(start);
}

void XfemCutter::save_state(StateWriter& out) const {
  out.tag("xfem cutter");
  out.value(rest_tets_.size());
  out.value(started_);
  out.value(continues_);
  out.value(last_);
  out.value(stats_);
  out.values(state_);
  std::vector<std::uint8_t> has_cut(cuts_.size(), 0);
  std::vector<ElementCut> cuts(cuts_.size());
  for (std::size_t t = 0; t < cuts_.size(); ++t) {
    has_cut[t] = cuts_[t] ? 1 : 0;
    cuts[t] = cuts_[t].value_or(ElementCut{});
  }
  out.values(has_cut);
  out.values(cuts);
  out.values(second_element_);
  out.values(rest_of_appended_);
  std::vector<std::pair<std::uint64_t, EdgeRecord>> edges(edges_.begin(), edges_.end());
  std::sort(edges.begin(), edges.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  out.values(edges);
  out.values(touched_);
  out.values(copy_of_);
  std::vector<std::pair<VertexId, std::vector<TetId>>> users(tied_users_.begin(),
                                                             tied_users_.end());
  std::sort(users.begin(), users.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<VertexId> tied_vertices;
  std::vector<std::vector<TetId>> tied_lists;
  for (auto& [v, list] : users) {
    tied_vertices.push_back(v);
    tied_lists.push_back(list);
  }
  out.values(tied_vertices);
  out.nested(tied_lists);
  out.values(front_);
  out.values(reached_at_);
  out.value(travel_);
}

void XfemCutter::load_state(StateReader& in) {
  in.tag("xfem cutter");
  if (in.value<std::size_t>("xfem rest tetrahedra") != rest_tets_.size()) {
    in.fail("xfem rest tetrahedra", "the checkpoint's mesh is not the scene's");
  }
  started_ = in.value<bool>("xfem started");
  continues_ = in.value<bool>("xfem stroke continues");
  last_ = in.value<BladePose>("xfem blade");
  stats_ = in.value<XfemCutterStats>("xfem stats");
  state_ = in.values<TetState>("xfem states");
  const auto has_cut = in.values<std::uint8_t>("xfem has cut");
  const auto cuts = in.values<ElementCut>("xfem cuts");
  if (state_.size() != rest_tets_.size() || has_cut.size() != rest_tets_.size() ||
      cuts.size() != rest_tets_.size()) {
    in.fail("xfem states", "one per rest tetrahedron");
  }
  for (std::size_t t = 0; t < cuts.size(); ++t) {
    cuts_[t] = has_cut[t] != 0 ? std::optional(cuts[t]) : std::nullopt;
  }
  second_element_ = in.values<TetId>("xfem second elements");
  rest_of_appended_ = in.values<TetId>("xfem appended elements");
  const auto edges = in.values<std::pair<std::uint64_t, EdgeRecord>>("xfem edges");
  edges_ = {edges.begin(), edges.end()};
  touched_ = in.values<std::uint8_t>("xfem touched");
  copy_of_ = in.values<VertexId>("xfem copies");
  const auto tied_vertices = in.values<VertexId>("xfem tied vertices");
  const auto tied_lists = in.nested<TetId>("xfem tied users");
  if (tied_vertices.size() != tied_lists.size() || touched_.size() != rest_vertices_ ||
      copy_of_.size() != rest_vertices_ || second_element_.size() != rest_tets_.size()) {
    in.fail("xfem tied users", "sizes do not match the mesh");
  }
  tied_users_.clear();
  for (std::size_t k = 0; k < tied_vertices.size(); ++k) {
    tied_users_[tied_vertices[k]] = tied_lists[k];
  }
  // The copies after each vertex's first are the mesh's other duplicates of it, in id order.
  more_copies_.clear();
  for (std::size_t v = rest_vertices_; v < mesh_->vertex_count(); ++v) {
    const auto id = static_cast<VertexId>(v);
    const VertexOrigin& origin = mesh_->vertex_origin(id);
    const VertexId original = origin.parents[0];
    if (origin.kind == VertexOrigin::Kind::kDuplicate && original >= 0 &&
        static_cast<std::size_t>(original) < rest_vertices_ &&
        copy_of_[static_cast<std::size_t>(original)] != id) {
      more_copies_[original].push_back(id);
    }
  }
  front_ = in.values<TetId>("xfem front");
  reached_at_ = in.values<std::pair<double, double>>("xfem reached");
  if (reached_at_.size() != rest_tets_.size()) {
    in.fail("xfem reached", "one per rest tetrahedron");
  }
  travel_ = in.value<double>("xfem travel");
  frozen_.clear();
  for (std::size_t t = 0; t < state_.size(); ++t) {
    if (state_[t] == TetState::kSplit) {
      freeze_edges(rest_tets_[t]);
    }
  }
}

}  // namespace incise
