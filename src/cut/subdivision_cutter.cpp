#include "incise/cut/subdivision_cutter.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"

namespace incise {
namespace {

void triangle_bounds(const std::array<Vec3, 3>& triangle, Vec3& low, Vec3& high) {
  low = triangle[0].cwiseMin(triangle[1]).cwiseMin(triangle[2]);
  high = triangle[0].cwiseMax(triangle[1]).cwiseMax(triangle[2]);
}

}  // namespace

SubdivisionCutter::SubdivisionCutter(TetMesh& mesh, const CutterOptions& options)
    : mesh_(mesh),
      options_(options),
      grid_(mesh),
      on_cut_(mesh, 0, VertexRule::kDefault),
      ancestry_(mesh, Ancestry{}, TetRule::kCopy) {
  if (!(options_.snap_fraction > 0.0 && options_.snap_fraction < 0.5)) {
    throw InputError("snap fraction must lie in (0, 0.5)");
  }
  // A copy of a vertex on the cut is on the cut too.
  on_cut_.set_hook([](VertexData<char>& data, VertexId vertex, const VertexOrigin& origin) {
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      data[vertex] = data[origin.parents[0]];
    }
  });
  // Every tetrahedron there is now is an original; children copy their parent's ancestry.
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    (void)ancestry(static_cast<TetId>(t));
  }
}

const Ancestry& SubdivisionCutter::ancestry(TetId tet) {
  Ancestry& entry = ancestry_[tet];
  if (entry.id < 0) {
    entry.id = static_cast<std::int32_t>(ancestor_codes_.size());
    ancestor_codes_.push_back(0);
    for (int a = 0; a < 4; ++a) {
      entry.corners[a] = mesh_.rest_position(mesh_.tet(tet)[a]);
    }
    entry.volume = std::abs(signed_volume(mesh_, tet));
  }
  return entry;
}

std::array<std::size_t, 7> SubdivisionCutter::accumulated_case_counts() const {
  std::array<std::size_t, 7> counts{};
  std::vector<char> seen(ancestor_codes_.size(), 0);
  for (std::size_t t = 0; t < mesh_.tet_count(); ++t) {
    const Ancestry& origin = ancestry_[static_cast<TetId>(t)];
    if (origin.id < 0 || seen[static_cast<std::size_t>(origin.id)] != 0) {
      continue;
    }
    seen[static_cast<std::size_t>(origin.id)] = 1;
    const std::uint8_t code = ancestor_codes_[static_cast<std::size_t>(origin.id)];
    if (code == 0) {
      continue;
    }
    const bool partial =
        started_ && segment_intersects_tet(pose_.tip, pose_.base, origin.corners[0],
                                           origin.corners[1], origin.corners[2], origin.corners[3]);
    ++counts[static_cast<std::size_t>(cut_case_table()[cut_state_key(code, partial)].kind)];
  }
  return counts;
}

double SubdivisionCutter::min_volume_ratio_to_original() const {
  double ratio = 1.0;
  for (std::size_t t = 0; t < mesh_.tet_count(); ++t) {
    const Ancestry& origin = ancestry_[static_cast<TetId>(t)];
    if (origin.id >= 0 && origin.volume > 0.0) {
      ratio =
          std::min(ratio, std::abs(signed_volume(mesh_, static_cast<TetId>(t))) / origin.volume);
    }
  }
  return ratio;
}

void SubdivisionCutter::start(const BladePose& pose) {
  pose_ = pose;
  started_ = true;
  track_point_tet();
  update_active_tets();
}

void SubdivisionCutter::cut_along(const std::vector<BladePose>& path) {
  if (path.empty()) {
    return;
  }
  start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    move_to(path[i]);
  }
}

void SubdivisionCutter::track_point_tet() {
  const Vec3& tip = pose_.tip;
  auto holds = [&](TetId t) {
    const Tet& v = mesh_.tet(t);
    return locate_in_tet(tip, mesh_.rest_position(v[0]), mesh_.rest_position(v[1]),
                         mesh_.rest_position(v[2]),
                         mesh_.rest_position(v[3])) != TetLocation::kOutside;
  };
  // The seed's search: the previous tetrahedron, then its neighbours, then everywhere (here
  // through the grid, so "everywhere" is local too).
  if (point_tet_ != kInvalidId && static_cast<std::size_t>(point_tet_) < mesh_.tet_count()) {
    if (holds(point_tet_)) {
      ++stats_.point_same;
      return;
    }
    for (TetId neighbor : mesh_.tet_neighbors(point_tet_)) {
      if (neighbor >= 0 && holds(neighbor)) {
        point_tet_ = neighbor;
        ++stats_.point_neighbor;
        return;
      }
    }
  }
  grid_.query(tip, tip, scratch_);
  point_tet_ = kInvalidId;
  for (TetId t : scratch_) {
    if (holds(t)) {
      point_tet_ = t;
      break;
    }
  }
  ++(point_tet_ == kInvalidId ? stats_.point_outside : stats_.point_global);
}

void SubdivisionCutter::update_active_tets() {
  active_.clear();
  grid_.query(pose_.tip.cwiseMin(pose_.base), pose_.tip.cwiseMax(pose_.base), scratch_);
  for (TetId t : scratch_) {
    const Tet& v = mesh_.tet(t);
    if (segment_intersects_tet(pose_.tip, pose_.base, mesh_.rest_position(v[0]),
                               mesh_.rest_position(v[1]), mesh_.rest_position(v[2]),
                               mesh_.rest_position(v[3]))) {
      active_.push_back(t);
    }
  }
}

bool SubdivisionCutter::is_cut_face(VertexId a, VertexId b, VertexId c) const {
  if (on_cut_[a] == 0 || on_cut_[b] == 0 || on_cut_[c] == 0) {
    return false;
  }
  const Vec3& pa = mesh_.rest_position(a);
  const Vec3& pb = mesh_.rest_position(b);
  const Vec3& pc = mesh_.rest_position(c);
  const double size = std::max({(pb - pa).norm(), (pc - pb).norm(), (pa - pc).norm()});
  // Vertices on the cut lie on the swept surface or within the snap distance of it; a face
  // between them belongs to the cut when its centroid does too.
  const double tolerance = options_.snap_fraction * size * 1.01;
  const Vec3 centroid = (pa + pb + pc) / 3.0;
  const double cell = grid_.cell_size();
  const Eigen::Array<long, 3, 1> low = ((centroid.array() - tolerance) / cell).floor().cast<long>();
  const Eigen::Array<long, 3, 1> high =
      ((centroid.array() + tolerance) / cell).floor().cast<long>();
  nearby_.clear();
  for (long k = low[2]; k <= high[2]; ++k) {
    for (long j = low[1]; j <= high[1]; ++j) {
      for (long i = low[0]; i <= high[0]; ++i) {
        const auto it = surface_cells_.find(cell_key(i, j, k));
        if (it != surface_cells_.end()) {
          nearby_.insert(nearby_.end(), it->second.begin(), it->second.end());
        }
      }
    }
  }
  for (std::uint32_t index : nearby_) {
    const auto& triangle = surface_[index];
    if (squared_distance_to_triangle(centroid, triangle[0], triangle[1], triangle[2]) <=
        tolerance * tolerance) {
      return true;
    }
  }
  return false;
}

std::uint64_t SubdivisionCutter::cell_key(long i, long j, long k) const {
  // 21 bits per axis, offset so negative cells hash too.
  const auto part = [](long value) {
    return static_cast<std::uint64_t>(value + (1L << 20)) & 0x1fffffU;
  };
  return part(i) << 42U | part(j) << 21U | part(k);
}

void SubdivisionCutter::index_triangle(std::size_t triangle) {
  const auto& t = surface_[triangle];
  const double cell = grid_.cell_size();
  const Eigen::Array<long, 3, 1> low =
      (t[0].cwiseMin(t[1]).cwiseMin(t[2]).array() / cell).floor().cast<long>();
  const Eigen::Array<long, 3, 1> high =
      (t[0].cwiseMax(t[1]).cwiseMax(t[2]).array() / cell).floor().cast<long>();
  for (long k = low[2]; k <= high[2]; ++k) {
    for (long j = low[1]; j <= high[1]; ++j) {
      for (long i = low[0]; i <= high[0]; ++i) {
        surface_cells_[cell_key(i, j, k)].push_back(static_cast<std::uint32_t>(triangle));
      }
    }
  }
}

std::size_t SubdivisionCutter::separate(VertexId vertex) {
  // Group the tetrahedra around the vertex: two are joined when they share a face through the
  // vertex that is not a cut face.
  const std::vector<TetId> around(mesh_.vertex_tets(vertex).begin(),
                                  mesh_.vertex_tets(vertex).end());
  if (around.size() < 2) {
    return 0;
  }
  std::vector<std::size_t> parent(around.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](std::size_t i) {
    while (parent[i] != i) {
      parent[i] = parent[parent[i]];
      i = parent[i];
    }
    return i;
  };
  std::map<TetId, std::size_t> index;
  for (std::size_t i = 0; i < around.size(); ++i) {
    index[around[i]] = i;
  }
  for (std::size_t i = 0; i < around.size(); ++i) {
    const TetId t = around[i];
    const Tet& tet = mesh_.tet(t);
    const int local = mesh_.local_index(t, vertex);
    for (int f = 0; f < 4; ++f) {
      if (f == local) {
        continue;  // the face opposite the vertex does not contain it
      }
      const TetId neighbor = mesh_.tet_neighbors(t)[f];
      if (neighbor < 0 || neighbor < t) {
        continue;
      }
      const auto& face = tet_local::kFaces[f];
      if (is_cut_face(tet[face[0]], tet[face[1]], tet[face[2]])) {
        continue;
      }
      const auto it = index.find(neighbor);
      if (it != index.end()) {
        parent[find(i)] = find(it->second);
      }
    }
  }
  std::map<std::size_t, std::vector<TetId>> groups;
  for (std::size_t i = 0; i < around.size(); ++i) {
    groups[find(i)].push_back(around[i]);
  }
  if (groups.size() < 2) {
    return 0;
  }
  // The group holding the smallest tet id keeps the vertex; every other group gets a copy.
  std::size_t copies = 0;
  bool first = true;
  for (auto& [root, tets] : groups) {
    if (first) {
      first = false;
      continue;
    }
    (void)mesh_.duplicate_vertex(vertex, tets);
    ++copies;
  }
  return copies;
}

void SubdivisionCutter::resolve_pinched_edges(std::vector<VertexId> vertices) {
  // Where the cut surface covers an edge whose two ends both lie on the crack front, neither end
  // can be separated and two wedges stay pinched along the edge (four boundary faces meet
  // there). Splitting the edge puts a vertex inside the cut, which can be separated.
  // Every round rescans the whole neighbourhood touched so far: separating one vertex can pinch
  // an edge between two others.
  for (int round = 0; round < 64; ++round) {
    std::vector<std::pair<VertexId, VertexId>> pinched;
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    // Groups around a vertex that now touch only along edges come apart first.
    const auto first_copy = static_cast<VertexId>(mesh_.vertex_count());
    for (std::size_t i = 0, n = vertices.size(); i < n; ++i) {
      stats_.vertices_duplicated += separate(vertices[i]);
    }
    for (auto v = first_copy; static_cast<std::size_t>(v) < mesh_.vertex_count(); ++v) {
      vertices.push_back(v);
    }
    for (VertexId v : vertices) {
      if (static_cast<std::size_t>(v) >= mesh_.vertex_count()) {
        continue;
      }
      std::map<VertexId, int> boundary_faces;
      for (TetId t : mesh_.vertex_tets(v)) {
        const Tet& tet = mesh_.tet(t);
        for (int f = 0; f < 4; ++f) {
          if (mesh_.tet_neighbors(t)[f] != kBoundaryFace || f == mesh_.local_index(t, v)) {
            continue;
          }
          for (int k : tet_local::kFaces[f]) {
            if (tet[k] != v) {
              ++boundary_faces[tet[k]];
            }
          }
        }
      }
      for (const auto& [w, count] : boundary_faces) {
        if (count > 2 && (on_cut_[v] != 0 || on_cut_[w] != 0)) {
          pinched.emplace_back(std::min(v, w), std::max(v, w));
        }
      }
    }
    std::sort(pinched.begin(), pinched.end());
    pinched.erase(std::unique(pinched.begin(), pinched.end()), pinched.end());
    if (pinched.empty()) {
      return;
    }
    for (const auto& [a, b] : pinched) {
      const EdgeId edge = mesh_.find_edge(a, b);
      if (edge == kInvalidId) {
        continue;  // already split this round through a neighbour
      }
      const auto first_new = static_cast<VertexId>(mesh_.vertex_count());
      const VertexId middle = split_edge(mesh_, edge, 0.5);
      // The wedges around the edge share no face, so the middle vertex separates them whether
      // or not it lies on the cut surface.
      on_cut_[middle] = on_cut_[a] != 0 && on_cut_[b] != 0 ? 1 : 0;
      ++stats_.edges_split;
      stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, 0.5);
      stats_.vertices_duplicated += separate(middle);
      for (VertexId v : {a, b}) {
        vertices.push_back(v);
      }
      for (auto v = first_new; static_cast<std::size_t>(v) < mesh_.vertex_count(); ++v) {
        vertices.push_back(v);  // the middle vertex and its copies
      }
    }
  }
}

void SubdivisionCutter::move_to(const BladePose& pose) {
  if (!started_) {
    start(pose);
    return;
  }
  const BladePose from = pose_;
  pose_ = pose;
  ++stats_.moves;

  // ---- collision detection: tets the swept surface touches, edges it crosses ---------------
  auto start = Clock::now();
  const auto triangles = swept_triangles(from, pose);
  std::vector<Crossing> crossings;
  std::vector<VertexId> snapped;
  std::vector<TetId> touched;
  for (const auto& triangle : triangles) {
    stats_.swept_area += 0.5 * (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]).norm();
    Vec3 low;
    Vec3 high;
    triangle_bounds(triangle, low, high);
    grid_.query(low, high, scratch_);
    for (TetId t : scratch_) {
      const Tet& v = mesh_.tet(t);
      // Bounding boxes first: the exact test is the expensive part of collision detection.
      Vec3 tet_low = mesh_.rest_position(v[0]);
      Vec3 tet_high = tet_low;
      for (int k = 1; k < 4; ++k) {
        tet_low = tet_low.cwiseMin(mesh_.rest_position(v[k]));
        tet_high = tet_high.cwiseMax(mesh_.rest_position(v[k]));
      }
      if ((tet_low.array() > high.array()).any() || (tet_high.array() < low.array()).any()) {
        continue;
      }
      if (triangle_intersects_tet(triangle[0], triangle[1], triangle[2], mesh_.rest_position(v[0]),
                                  mesh_.rest_position(v[1]), mesh_.rest_position(v[2]),
                                  mesh_.rest_position(v[3]))) {
        touched.push_back(t);
      }
    }
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  stats_.candidate_tets = touched.size();
  std::vector<std::pair<VertexId, VertexId>> edges;
  for (TetId t : touched) {
    const Tet& v = mesh_.tet(t);
    for (const auto& e : tet_local::kEdges) {
      edges.emplace_back(std::min(v[e[0]], v[e[1]]), std::max(v[e[0]], v[e[1]]));
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [a, b] : edges) {
    const Vec3& pa = mesh_.rest_position(a);
    const Vec3& pb = mesh_.rest_position(b);
    for (const auto& triangle : triangles) {
      if (!segment_intersects_triangle(pa, pb, triangle[0], triangle[1], triangle[2])) {
        continue;
      }
      const Vec3 normal = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]);
      const double da = normal.dot(pa - triangle[0]);
      const double db = normal.dot(pb - triangle[0]);
      if (da == db) {
        // The edge lies in the blade's plane: its ends on the swept triangle are on the cut.
        for (VertexId end : {a, b}) {
          const Vec3& p = mesh_.rest_position(end);
          if (squared_distance_to_triangle(p, triangle[0], triangle[1], triangle[2]) <=
              1e-24 * normal.norm()) {
            snapped.push_back(end);
          }
        }
        break;
      }
      const double t = std::clamp(da / (da - db), 0.0, 1.0);
      if (t <= options_.snap_fraction) {
        snapped.push_back(a);
      } else if (t >= 1.0 - options_.snap_fraction) {
        snapped.push_back(b);
      } else {
        crossings.push_back({a, b, t});
      }
      break;
    }
  }
  // The seed's cut-edge code of every tetrahedron this move crossed, and its case.
  {
    std::vector<std::pair<VertexId, VertexId>> crossed;
    for (const Crossing& crossing : crossings) {
      crossed.emplace_back(std::min(crossing.a, crossing.b), std::max(crossing.a, crossing.b));
    }
    std::sort(crossed.begin(), crossed.end());
    // Accumulate on each original tetrahedron the edges of its own that the crossings lie on
    // (a crossing inside one of its faces or its interior is not an original edge).
    for (TetId t : touched) {
      const Ancestry& origin = ancestry(t);
      for (const Crossing& crossing : crossings) {
        if (mesh_.local_index(t, crossing.a) < 0 || mesh_.local_index(t, crossing.b) < 0) {
          continue;
        }
        const Vec3 point = (1.0 - crossing.t) * mesh_.rest_position(crossing.a) +
                           crossing.t * mesh_.rest_position(crossing.b);
        Mat3 frame;
        frame << origin.corners[1] - origin.corners[0], origin.corners[2] - origin.corners[0],
            origin.corners[3] - origin.corners[0];
        const Vec3 local = frame.inverse() * (point - origin.corners[0]);
        const std::array<double, 4> weights{1.0 - local.sum(), local[0], local[1], local[2]};
        int nonzero[2] = {-1, -1};
        int count = 0;
        for (int k = 0; k < 4; ++k) {
          if (std::abs(weights[k]) > 1e-9) {
            if (count < 2) {
              nonzero[count] = k;
            }
            ++count;
          }
        }
        if (count != 2) {
          continue;
        }
        for (int k = 0; k < 6; ++k) {
          const auto& e = tet_local::kEdges[k];
          if ((e[0] == nonzero[0] && e[1] == nonzero[1]) ||
              (e[0] == nonzero[1] && e[1] == nonzero[0])) {
            ancestor_codes_[static_cast<std::size_t>(origin.id)] |=
                static_cast<std::uint8_t>(1U << k);
          }
        }
      }
    }
    for (TetId t : touched) {
      const Tet& v = mesh_.tet(t);
      std::uint8_t code = 0;
      for (int k = 0; k < 6; ++k) {
        const auto& e = tet_local::kEdges[k];
        if (std::binary_search(crossed.begin(), crossed.end(),
                               std::pair{std::min(v[e[0]], v[e[1]]), std::max(v[e[0]], v[e[1]])})) {
          code = static_cast<std::uint8_t>(code | 1U << k);
        }
      }
      if (code == 0) {
        continue;
      }
      const bool partial = segment_intersects_tet(
          pose.tip, pose.base, mesh_.rest_position(v[0]), mesh_.rest_position(v[1]),
          mesh_.rest_position(v[2]), mesh_.rest_position(v[3]));
      ++stats_.case_counts[static_cast<std::size_t>(
          cut_case_table()[cut_state_key(code, partial)].kind)];
    }
  }
  stats_.cd_seconds = seconds_since(start);

  // ---- topology and geometry changes ---------------------------------------------------------
  start = Clock::now();
  for (VertexId v : snapped) {
    if (on_cut_[v] == 0) {
      on_cut_[v] = 1;
      ++stats_.vertices_snapped;
    }
  }
  for (const Crossing& crossing : crossings) {
    if (on_cut_[crossing.a] != 0 && on_cut_[crossing.b] != 0) {
      continue;  // both ends already on the cut: the crossing is the cut itself
    }
    const EdgeId edge = mesh_.find_edge(crossing.a, crossing.b);
    INCISE_ASSERT(edge != kInvalidId, "a crossed edge vanished before it was split");
    const double t = mesh_.edge(edge)[0] == crossing.a ? crossing.t : 1.0 - crossing.t;
    const VertexId middle = split_edge(mesh_, edge, t);
    on_cut_[middle] = 1;
    ++stats_.edges_split;
    stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, std::min(t, 1.0 - t));
  }
  for (const auto& triangle : triangles) {
    surface_.push_back(triangle);
    index_triangle(surface_.size() - 1);
  }

  // Open the cut: vertices on it near this move's surface, separated where cut faces part
  // their tetrahedra. Faces counted once, before separation.
  std::vector<VertexId> candidates;
  std::vector<std::array<VertexId, 3>> opened;
  for (const auto& triangle : triangles) {
    Vec3 low;
    Vec3 high;
    triangle_bounds(triangle, low, high);
    const Vec3 margin = Vec3::Constant(grid_.cell_size() * 0.5);
    grid_.query(low - margin, high + margin, scratch_);
    for (TetId t : scratch_) {
      for (VertexId v : mesh_.tet(t)) {
        if (on_cut_[v] != 0) {
          candidates.push_back(v);
        }
      }
      const Tet& tet = mesh_.tet(t);
      for (int f = 0; f < 4; ++f) {
        const TetId neighbor = mesh_.tet_neighbors(t)[f];
        const auto& face = tet_local::kFaces[f];
        if (neighbor > t && is_cut_face(tet[face[0]], tet[face[1]], tet[face[2]])) {
          std::array<VertexId, 3> key{tet[face[0]], tet[face[1]], tet[face[2]]};
          std::sort(key.begin(), key.end());
          opened.push_back(key);
        }
      }
    }
  }
  std::sort(opened.begin(), opened.end());
  opened.erase(std::unique(opened.begin(), opened.end()), opened.end());
  for (const auto& face : opened) {
    const Vec3& p0 = mesh_.rest_position(face[0]);
    stats_.cut_area +=
        0.5 * (mesh_.rest_position(face[1]) - p0).cross(mesh_.rest_position(face[2]) - p0).norm();
  }
  stats_.cut_faces += opened.size();
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  const auto first_copy = static_cast<VertexId>(mesh_.vertex_count());
  for (VertexId v : candidates) {
    stats_.vertices_duplicated += separate(v);
  }
  // Copies made by the separation can be pinched too.
  for (auto v = first_copy; static_cast<std::size_t>(v) < mesh_.vertex_count(); ++v) {
    candidates.push_back(v);
  }
  resolve_pinched_edges(candidates);
  stats_.gc_seconds = seconds_since(start);
  stats_.total_cd_seconds += stats_.cd_seconds;
  stats_.total_gc_seconds += stats_.gc_seconds;

  track_point_tet();
  update_active_tets();
}

}  // namespace incise
