#include "incise/cut/subdivision_cutter.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <unordered_set>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "triangle_index.hpp"

namespace incise {
namespace {

double longest_edge(const std::array<Vec3, 3>& t) {
  return std::max({(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()});
}

/// The vertices of a tetrahedron's face, sorted: one key per face whichever tet it is seen from.
std::array<VertexId, 3> face_key(const Tet& tet, int local_face) {
  const auto& face = tet_local::kFaces[local_face];
  std::array<VertexId, 3> key{tet[face[0]], tet[face[1]], tet[face[2]]};
  std::sort(key.begin(), key.end());
  return key;
}

double longest_edge(const std::array<Vec3, 4>& corners) {
  double longest = 0.0;
  for (const auto& e : tet_local::kEdges) {
    longest = std::max(longest, (corners[e[0]] - corners[e[1]]).norm());
  }
  return longest;
}

std::array<Vec3, 4> rest_corners(const TetMesh& mesh, TetId tet) {
  const Tet& v = mesh.tet(tet);
  return {mesh.rest_position(v[0]), mesh.rest_position(v[1]), mesh.rest_position(v[2]),
          mesh.rest_position(v[3])};
}

/// A face's corners at rest, in tet_local::kFaces order.
std::array<Vec3, 3> rest_face(const TetMesh& mesh, TetId tet, int local_face) {
  const Tet& v = mesh.tet(tet);
  const auto& face = tet_local::kFaces[local_face];
  return {mesh.rest_position(v[face[0]]), mesh.rest_position(v[face[1]]),
          mesh.rest_position(v[face[2]])};
}

double area(const std::array<Vec3, 3>& t) {
  return 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
}

Vec3 centroid(const std::array<Vec3, 3>& corners) {
  return (corners[0] + corners[1] + corners[2]) / 3.0;
}

Vec3 centroid(const std::array<Vec3, 4>& corners) {
  return (corners[0] + corners[1] + corners[2] + corners[3]) / 4.0;
}

/// Which side (-1, +1) of the plane of `triangle` a point is on (+1 on the plane).
// Normalized volumes (1: regular). Blade-line vertices are optional (the crossings of the
// swept surface open the cut without them), so one that would thin the tetrahedra around it
// towards degenerate (1e-6) is left out: no child or slid tetrahedron goes below this floor
// unless it was there already, however many tiny steps the blade takes.
constexpr double kQualityFloor = 1e-4;

// A slide may also thin a tetrahedron by at most half per pose below 0.05.
double slide_floor(double before) {
  constexpr double kGood = 0.05;
  return std::max(std::min(kGood, 0.5 * before), std::min(before, kQualityFloor));
}

double quality(const std::array<Vec3, 4>& corners) {
  return normalized_volume(corners[0], corners[1], corners[2], corners[3]);
}

int side_of(const Vec3& point, const std::array<Vec3, 3>& triangle) {
  const Vec3 normal = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]);
  return normal.dot(point - triangle[0]) < 0.0 ? -1 : 1;
}

/// Distance (m) from a point to the nearest of some triangles (infinity when there are none).
double distance_to(const std::vector<std::array<Vec3, 3>>& triangles, const Vec3& point) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : triangles) {
    best = std::min(best, squared_distance_to_triangle(point, t[0], t[1], t[2]));
  }
  return std::sqrt(best);
}

void triangle_bounds(const std::array<Vec3, 3>& triangle, Vec3& low, Vec3& high) {
  low = triangle[0].cwiseMin(triangle[1]).cwiseMin(triangle[2]);
  high = triangle[0].cwiseMax(triangle[1]).cwiseMax(triangle[2]);
}

}  // namespace

SubdivisionCutter::SubdivisionCutter(TetMesh& mesh, const CutterOptions& options,
                                     const VertexData<Vec3>* positions)
    : mesh_(mesh),
      options_(options),
      positions_(positions),
      grid_(mesh, positions),
      marks_(mesh),
      on_cut_(mesh, 0, VertexRule::kDefault),
      cut_offset_(mesh, 0.0, VertexRule::kDefault),
      ancestry_(mesh, Ancestry{}, TetRule::kCopy) {
  swept_ = std::make_unique<detail::TriangleIndex>(grid_.cell_size() / 64.0);
  if (!(options_.snap_fraction > 0.0 && options_.snap_fraction < 0.5)) {
    throw InputError("snap fraction must lie in (0, 0.5)");
  }
  if (positions_ != nullptr && positions_->size() != mesh.vertex_count()) {
    throw InputError("the cutter's positions do not belong to its mesh");
  }
  // A copy of a vertex on the cut is on the cut too.
  on_cut_.set_hook([](VertexData<char>& data, VertexId vertex, const VertexOrigin& origin) {
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      data[vertex] = data[origin.parents[0]];
    }
  });
  // A point between vertices lies no farther from a plane than the farthest of them.
  cut_offset_.set_hook([](VertexData<double>& data, VertexId vertex, const VertexOrigin& origin) {
    double offset = 0.0;
    for (int p = 0; p < origin.parent_count; ++p) {
      offset = std::max(offset, data[origin.parents[static_cast<std::size_t>(p)]]);
    }
    data[vertex] = offset;
  });
  // Every tetrahedron there is now is an original; children copy their parent's ancestry.
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    (void)ancestry(static_cast<TetId>(t));
  }
}

SubdivisionCutter::~SubdivisionCutter() = default;

const Ancestry& SubdivisionCutter::ancestry(TetId tet) {
  Ancestry& entry = ancestry_[tet];
  if (entry.id < 0) {
    entry.id = static_cast<std::int32_t>(ancestor_codes_.size());
    ancestor_codes_.push_back(0);
    ancestor_presplit_.push_back(0);
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
  // An original is partly cut while the blade is inside one of its descendants.
  std::vector<char> under_blade(ancestor_codes_.size(), 0);
  for (TetId t : active_) {
    const std::int32_t id = ancestry_[t].id;
    if (id >= 0) {
      under_blade[static_cast<std::size_t>(id)] = 1;
    }
  }
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
    const bool partial = under_blade[static_cast<std::size_t>(origin.id)] != 0;
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

SubdivisionCutter::MaterialPoint SubdivisionCutter::material_point(const Vec3& point) {
  MaterialPoint result;
  const TetId holder = locate(point);
  if (holder != kInvalidId) {
    result.vertices = mesh_.tet(holder);
    result.weights = weights_in(point, holder);
  }
  return result;
}

TetId SubdivisionCutter::locate(const Vec3& point) {
  grid_.query(point, point, scratch_);
  for (TetId t : scratch_) {
    const Tet& v = mesh_.tet(t);
    if (locate_in_tet(point, position(v[0]), position(v[1]), position(v[2]), position(v[3])) !=
        TetLocation::kOutside) {
      return t;
    }
  }
  return kInvalidId;
}

std::array<double, 4> SubdivisionCutter::weights_in(const Vec3& point, TetId tet) const {
  const Tet& v = mesh_.tet(tet);
  return barycentric_coordinates(point, position(v[0]), position(v[1]), position(v[2]),
                                 position(v[3]));
}

Vec3 SubdivisionCutter::current(const MaterialPoint& point, const Vec3& fallback) const {
  if (point.vertices[0] == kInvalidId) {
    return fallback;
  }
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    sum += point.weights[k] * position(point.vertices[k]);
  }
  return sum;
}

void SubdivisionCutter::start(const BladePose& pose) {
  pose_ = pose;
  started_ = true;
  provisional_.clear();  // a new stroke: the last one's blade-line vertices stay where they are
  track_point_tet();
  update_active_tets();
  if (positions_ != nullptr) {
    tip_material_ = material_point(pose.tip);
    base_material_ = material_point(pose.base);
  }
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
    return locate_in_tet(tip, position(v[0]), position(v[1]), position(v[2]), position(v[3])) !=
           TetLocation::kOutside;
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
  point_tet_ = locate(tip);
  ++(point_tet_ == kInvalidId ? stats_.point_outside : stats_.point_global);
}

void SubdivisionCutter::update_active_tets() {
  active_.clear();
  grid_.query(pose_.tip.cwiseMin(pose_.base), pose_.tip.cwiseMax(pose_.base), scratch_);
  for (TetId t : scratch_) {
    const Tet& v = mesh_.tet(t);
    if (segment_intersects_tet(pose_.tip, pose_.base, position(v[0]), position(v[1]),
                               position(v[2]), position(v[3]))) {
      active_.push_back(t);
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
    const int local = mesh_.local_index(t, vertex);
    for (int f = 0; f < 4; ++f) {
      if (f == local) {
        continue;  // the face opposite the vertex does not contain it
      }
      const TetId neighbor = mesh_.tet_neighbors(t)[f];
      if (neighbor < 0 || neighbor < t) {
        continue;
      }
      if (marks_.is_cut(t, f)) {
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
    separated_.push_back(vertex);
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
      if (on_cut_[middle] != 0) {
        // The split moved the centroids of the tetrahedra around the edge: decide the faces
        // around the middle vertex again.
        fresh_.assign(1, middle);
        for (VertexId corner : mark_cut_faces()) {
          vertices.push_back(corner);
        }
      }
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

SubdivisionCutter::Contact SubdivisionCutter::detect(
    const std::vector<std::array<Vec3, 3>>& triangles) {
  Contact contact;
  for (const auto& triangle : triangles) {
    Vec3 low;
    Vec3 high;
    triangle_bounds(triangle, low, high);
    grid_.query(low, high, scratch_);
    for (TetId t : scratch_) {
      const Tet& v = mesh_.tet(t);
      // Bounding boxes first: the exact test is the expensive part of collision detection.
      Vec3 tet_low = position(v[0]);
      Vec3 tet_high = tet_low;
      for (int k = 1; k < 4; ++k) {
        tet_low = tet_low.cwiseMin(position(v[k]));
        tet_high = tet_high.cwiseMax(position(v[k]));
      }
      if ((tet_low.array() > high.array()).any() || (tet_high.array() < low.array()).any()) {
        continue;
      }
      if (triangle_intersects_tet(triangle[0], triangle[1], triangle[2], position(v[0]),
                                  position(v[1]), position(v[2]), position(v[3]))) {
        contact.touched.push_back(t);
      }
    }
  }
  std::sort(contact.touched.begin(), contact.touched.end());
  contact.touched.erase(std::unique(contact.touched.begin(), contact.touched.end()),
                        contact.touched.end());
  std::vector<std::pair<VertexId, VertexId>> edges;
  for (TetId t : contact.touched) {
    const Tet& v = mesh_.tet(t);
    for (const auto& e : tet_local::kEdges) {
      edges.emplace_back(std::min(v[e[0]], v[e[1]]), std::max(v[e[0]], v[e[1]]));
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [a, b] : edges) {
    const Vec3& pa = position(a);
    const Vec3& pb = position(b);
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
          if (squared_distance_to_triangle(position(end), triangle[0], triangle[1], triangle[2]) <=
              1e-24 * normal.norm()) {
            contact.snapped.push_back(end);
          }
        }
        break;
      }
      const double t = std::clamp(da / (da - db), 0.0, 1.0);
      if (t <= options_.snap_fraction) {
        contact.snapped.push_back(a);
      } else if (t >= 1.0 - options_.snap_fraction) {
        contact.snapped.push_back(b);
      } else {
        contact.crossings.push_back({a, b, t});
      }
      break;
    }
  }
  return contact;
}

void SubdivisionCutter::record_swept(const std::vector<std::array<Vec3, 3>>& triangles,
                                     const Contact& contact) {
  move_rest_triangles_.clear();
  if (positions_ == nullptr) {
    for (const auto& triangle : triangles) {
      swept_->add(triangle);
      move_rest_triangles_.push_back(triangle);
    }
    return;
  }
  for (TetId t : contact.touched) {
    const Tet& v = mesh_.tet(t);
    Mat3 world;
    Mat3 rest;
    for (int k = 0; k < 3; ++k) {
      world.col(k) = position(v[k + 1]) - position(v[0]);
      rest.col(k) = mesh_.rest_position(v[k + 1]) - mesh_.rest_position(v[0]);
    }
    if (!(std::abs(world.determinant()) > 0.0)) {
      continue;  // flattened in the current configuration: no map to rest from it
    }
    const Mat3 to_rest = rest * world.inverse();
    Vec3 low = mesh_.rest_position(v[0]);
    Vec3 high = low;
    double size = 0.0;
    for (int k = 1; k < 4; ++k) {
      low = low.cwiseMin(mesh_.rest_position(v[k]));
      high = high.cwiseMax(mesh_.rest_position(v[k]));
      size = std::max(size, rest.col(k - 1).norm());
    }
    const Vec3 margin = Vec3::Constant(1e-9 * size);
    for (const auto& triangle : triangles) {
      std::array<Vec3, 3> image;
      for (int k = 0; k < 3; ++k) {
        image[k] = mesh_.rest_position(v[0]) + to_rest * (triangle[k] - position(v[0]));
      }
      swept_->add(image, low - margin, high + margin);
      move_rest_triangles_.push_back(image);
    }
  }
}

void SubdivisionCutter::classify(const Contact& contact, const BladePose& pose) {
  std::vector<std::pair<VertexId, VertexId>> crossed;
  for (const Crossing& crossing : contact.crossings) {
    crossed.emplace_back(std::min(crossing.a, crossing.b), std::max(crossing.a, crossing.b));
  }
  std::sort(crossed.begin(), crossed.end());
  // The seed's per-move code and case of every tetrahedron this move crossed.
  for (TetId t : contact.touched) {
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
    const bool partial = segment_intersects_tet(pose.tip, pose.base, position(v[0]), position(v[1]),
                                                position(v[2]), position(v[3]));
    ++stats_.case_counts[static_cast<std::size_t>(
        cut_case_table()[cut_state_key(code, partial)].kind)];
  }
}

void SubdivisionCutter::mark_on_cut(VertexId vertex, double offset) {
  on_cut_[vertex] = 1;
  cut_offset_[vertex] = offset;
  fresh_.push_back(vertex);
  // The seed's cut-edge codes, accumulated on the originals: a vertex on the cut inside an
  // edge of an original tetrahedron (at rest, where the original's corners are) cuts that edge,
  // whichever move or operation put it there.
  const Vec3& point = mesh_.rest_position(vertex);
  for (TetId t : mesh_.vertex_tets(vertex)) {
    const Ancestry& origin = ancestry(t);
    const std::array<double, 4> weights = barycentric_coordinates(
        point, origin.corners[0], origin.corners[1], origin.corners[2], origin.corners[3]);
    int ends[2] = {-1, -1};
    int count = 0;
    for (int k = 0; k < 4; ++k) {
      if (std::abs(weights[k]) > 1e-9) {
        if (count < 2) {
          ends[count] = k;
        }
        ++count;
      }
    }
    if (count != 2) {
      continue;
    }
    for (int k = 0; k < 6; ++k) {
      const auto& e = tet_local::kEdges[k];
      if ((e[0] == ends[0] && e[1] == ends[1]) || (e[0] == ends[1] && e[1] == ends[0])) {
        ancestor_codes_[static_cast<std::size_t>(origin.id)] |= static_cast<std::uint8_t>(1U << k);
      }
    }
  }
}

void SubdivisionCutter::insert_blade_points(const BladePose& pose, const Vec3& normal) {
  // Where the blade line enters and leaves each tetrahedron it passes through (and its tip or
  // base where they are inside), as parameters from the tip (0) to the base (1).
  const Vec3 direction = pose.base - pose.tip;
  if (direction.squaredNorm() == 0.0) {
    return;
  }
  grid_.query(pose.tip.cwiseMin(pose.base), pose.tip.cwiseMax(pose.base), scratch_);
  std::vector<double> parameters;
  for (TetId t : scratch_) {
    const Tet& v = mesh_.tet(t);
    const std::array<Vec3, 4> p{position(v[0]), position(v[1]), position(v[2]), position(v[3])};
    if (!segment_intersects_tet(pose.tip, pose.base, p[0], p[1], p[2], p[3])) {
      continue;
    }
    double enter = 0.0;
    double leave = 1.0;
    for (int f = 0; f < 4; ++f) {
      const auto& face = tet_local::kFaces[f];
      Vec3 inward = (p[face[1]] - p[face[0]]).cross(p[face[2]] - p[face[0]]);
      if (inward.dot(p[f] - p[face[0]]) < 0.0) {
        inward = -inward;  // towards the opposite vertex
      }
      const double at_tip = inward.dot(pose.tip - p[face[0]]);
      const double rate = inward.dot(direction);
      if (rate > 0.0) {
        enter = std::max(enter, -at_tip / rate);
      } else if (rate < 0.0) {
        leave = std::min(leave, -at_tip / rate);
      }
    }
    if (enter <= leave) {
      parameters.push_back(enter);
      parameters.push_back(leave);
    }
  }
  std::sort(parameters.begin(), parameters.end());
  parameters.erase(std::unique(parameters.begin(), parameters.end(),
                               [](double a, double b) { return b - a < 1e-12; }),
                   parameters.end());
  for (double s : parameters) {
    insert_point(pose.tip + s * direction, normal);
  }
}

bool SubdivisionCutter::splits_well(TetId holder, const std::array<double, 4>& weights) const {
  // The tetrahedra the split replaces: the holder, and those sharing the face or edge the
  // point lies on. Each child takes the point in place of one corner of that feature.
  const Tet& v = mesh_.tet(holder);
  std::vector<VertexId> feature;
  Vec3 point = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    if (weights[k] > 0.0) {
      feature.push_back(v[k]);
      point += weights[k] * mesh_.rest_position(v[k]);
    }
  }
  std::vector<TetId> around{holder};
  if (feature.size() == 3) {
    const int opposite =
        static_cast<int>(std::find(weights.begin(), weights.end(), 0.0) - weights.begin());
    const TetId neighbor = mesh_.tet_neighbors(holder)[opposite];
    if (neighbor >= 0) {
      around.push_back(neighbor);
    }
  } else if (feature.size() == 2) {
    const EdgeId edge = mesh_.find_edge(feature[0], feature[1]);
    around.assign(mesh_.edge_tets(edge).begin(), mesh_.edge_tets(edge).end());
  }
  for (TetId t : around) {
    const std::array<Vec3, 4> corners = rest_corners(mesh_, t);
    const double floor = std::min(kQualityFloor, quality(corners));
    for (VertexId x : feature) {
      std::array<Vec3, 4> child = corners;
      child[mesh_.local_index(t, x)] = point;
      if (quality(child) < floor) {
        return false;
      }
    }
  }
  return true;
}

void SubdivisionCutter::insert_point(const Vec3& point, const Vec3& normal) {
  const TetId holder = locate(point);
  if (holder == kInvalidId) {
    return;  // outside the body, or in the gap of an opened cut
  }
  const Tet v = mesh_.tet(holder);
  // Growth that does not depend on how finely the path is sampled: where a vertex already on
  // the cut lies within the snap distance of the original tetrahedron (not of the ever smaller
  // children the blade leaves behind), the wound reaches the blade to within that distance
  // already and no vertex is added.
  if (options_.merge_blade_points) {
    const double original_size = longest_edge(ancestry(holder).corners);
    for (VertexId x : v) {
      if (on_cut_[x] != 0 &&
          (position(x) - point).norm() <= options_.snap_fraction * original_size) {
        return;
      }
    }
  }
  std::array<double, 4> weights = weights_in(point, holder);
  // A point close to a face, edge or vertex of its tetrahedron (relative to the element) snaps
  // onto it, so no child is thinner than the snap fraction of its parent, but only where that
  // moves it within the swept surface (away from vertices that lie on the surface): a vertex
  // put on the cut must lie on it. A point that would move off the surface is left out; near
  // it, the cut opens as the crossings of the swept surface place it.
  const double round_off = 1e-9;
  const int largest =
      static_cast<int>(std::max_element(weights.begin(), weights.end()) - weights.begin());
  std::array<double, 4> snapped = weights;
  double sum = 0.0;
  for (int k = 0; k < 4; ++k) {
    if (k != largest && weights[k] < options_.snap_fraction) {
      snapped[k] = 0.0;
    }
    sum += snapped[k];
  }
  Vec3 moved = Vec3::Zero();
  double size = 0.0;
  for (int k = 0; k < 4; ++k) {
    snapped[k] /= sum;
    moved += snapped[k] * position(v[k]);
    size = std::max(size, (position(v[k]) - position(v[(k + 1) % 4])).norm());
  }
  if (std::abs(normal.dot(moved - point)) > round_off * size) {
    return;
  }
  // Snapping within the plane may move the point ahead of the blade (by less than the snap
  // distance): remember how far, so faces through it are taken as on the cut.
  const double offset = std::max(round_off * size, distance_to(move_triangles_, moved));
  weights = snapped;
  int count = 0;
  double smallest = 1.0;
  for (double w : weights) {
    if (w > 0.0) {
      ++count;
      smallest = std::min(smallest, w);
    }
  }
  // A point on a face, edge or vertex that lies in the cut already needs nothing.
  bool all_on_cut = true;
  for (int k = 0; k < 4; ++k) {
    if (weights[k] > 0.0 && on_cut_[v[k]] == 0) {
      all_on_cut = false;
    }
  }
  if (count < 4 && all_on_cut) {
    return;
  }
  VertexId inserted = kInvalidId;
  if (count == 1) {
    mark_on_cut(v[largest], offset);  // not on the cut yet: returned above
    ++stats_.vertices_snapped;
    return;
  }
  if (!splits_well(holder, weights)) {
    ++stats_.blade_points_left_out;
    return;
  }
  if (count == 2) {
    int ends[2] = {-1, -1};
    for (int k = 0, n = 0; k < 4; ++k) {
      if (weights[k] > 0.0) {
        ends[n++] = k;
      }
    }
    const EdgeId edge = mesh_.find_edge(v[ends[0]], v[ends[1]]);
    INCISE_ASSERT(edge != kInvalidId, "a tetrahedron's edge is missing");
    const double t = mesh_.edge(edge)[1] == v[ends[1]] ? weights[ends[1]] : weights[ends[0]];
    inserted = split_edge(mesh_, edge, t);
    ++stats_.edges_split;
  } else if (count == 3) {
    const int opposite =
        static_cast<int>(std::find(weights.begin(), weights.end(), 0.0) - weights.begin());
    const auto& face = tet_local::kFaces[opposite];
    inserted =
        split_face(mesh_, holder, opposite, {weights[face[0]], weights[face[1]], weights[face[2]]});
  } else {
    inserted = split_tet(mesh_, holder, weights);
  }
  mark_on_cut(inserted, offset);
  if (sliding_ && count >= 3) {
    // On a face or inside a tetrahedron: it may slide along with the blade next pose.
    Provisional slider{inserted, {}, count};
    if (count == 3) {
      const int opposite =
          static_cast<int>(std::find(weights.begin(), weights.end(), 0.0) - weights.begin());
      for (int k = 0; k < 3; ++k) {
        slider.corners[k] = v[tet_local::kFaces[opposite][k]];
      }
    } else {
      slider.corners = v;
    }
    next_provisional_.push_back(slider);
  }
  ++stats_.blade_vertices;
  stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, smallest);
}

double SubdivisionCutter::cut_area_around(VertexId vertex) const {
  // Each cut face through the vertex is seen from two tetrahedra around it (its two sides, or
  // the two copies of a face the cut opened while the vertex itself stayed joined).
  double total = 0.0;
  for (TetId t : mesh_.vertex_tets(vertex)) {
    const int local = mesh_.local_index(t, vertex);
    for (int f = 0; f < 4; ++f) {
      if (f != local && marks_.is_cut(t, f)) {
        total += 0.5 * area(rest_face(mesh_, t, f));
      }
    }
  }
  return total;
}

void SubdivisionCutter::slide_blade_points(const BladePose& pose) {
  const Vec3 direction = pose.base - pose.tip;

  for (const Provisional& point : provisional_) {
    // Where the new blade line meets the feature the vertex was put in: the plane of its face,
    // or the tetrahedron holding the tip (at the positions the cutter intersects).
    std::array<double, 4> weights{};
    std::array<Vec3, 4> feature;
    for (int k = 0; k < point.count; ++k) {
      feature[k] = position(point.corners[k]);
    }
    if (point.count == 3) {
      const Vec3 normal = (feature[1] - feature[0]).cross(feature[2] - feature[0]);
      const double rate = normal.dot(direction);
      if (rate == 0.0) {
        continue;
      }
      const double s = normal.dot(feature[0] - pose.tip) / rate;
      if (!(s >= 0.0 && s <= 1.0)) {
        continue;
      }
      const Vec3 q = pose.tip + s * direction;
      const double area = normal.norm();
      const double wa = normal.dot((feature[1] - q).cross(feature[2] - q)) / (area * area);
      const double wb = normal.dot((feature[2] - q).cross(feature[0] - q)) / (area * area);
      weights = {wa, wb, 1.0 - wa - wb, 0.0};
    } else {
      weights = barycentric_coordinates(pose.tip, feature[0], feature[1], feature[2], feature[3]);
    }
    // Not closer to the feature's boundary than the snap fraction: there the blade is about to
    // leave it, and the crossing of its edge is split next.
    bool inside = true;
    for (int k = 0; k < point.count; ++k) {
      inside = inside && weights[k] >= options_.snap_fraction;
    }
    if (!inside) {
      continue;  // the blade left the face or tetrahedron: the vertex stays behind
    }
    Vec3 rest = Vec3::Zero();
    Vec3 now = Vec3::Zero();
    for (int k = 0; k < point.count; ++k) {
      rest += weights[k] * mesh_.rest_position(point.corners[k]);
      now += weights[k] * feature[k];
    }
    // Every tetrahedron around it stays positive and no thinner than the floor (or than it
    // was), at rest and where the cutter intersects.
    const VertexId vertex = point.vertex;
    bool ok = true;
    for (TetId t : mesh_.vertex_tets(vertex)) {
      const Tet& v = mesh_.tet(t);
      const int local = mesh_.local_index(t, vertex);
      const std::array<Vec3, 4> before = rest_corners(mesh_, t);
      std::array<Vec3, 4> after = before;
      after[local] = rest;
      ok = orient3d(after[0], after[1], after[2], after[3]) == Sign::kPositive &&
           quality(after) >= slide_floor(quality(before));
      if (ok && positions_ != nullptr) {
        std::array<Vec3, 4> current{position(v[0]), position(v[1]), position(v[2]), position(v[3])};
        current[local] = now;
        ok = orient3d(current[0], current[1], current[2], current[3]) == Sign::kPositive;
      }
      if (!ok) {
        break;
      }
    }
    if (!ok) {
      continue;
    }
    // Inside its face or tetrahedron, the tetrahedra around it fill the same star wherever it
    // moves (all stay positive), so volume and boundary are kept.
    stats_.cut_area -= cut_area_around(vertex);
    mesh_.relocate_vertex(vertex, std::span(point.corners.data(), point.count),
                          std::span(weights.data(), point.count));
    stats_.cut_area += cut_area_around(vertex);
    double size = 0.0;
    for (TetId t : mesh_.vertex_tets(vertex)) {
      size = std::max(size, longest_edge(rest_corners(mesh_, t)));
    }
    mark_on_cut(vertex, 1e-9 * size);
    next_provisional_.push_back(point);
    ++stats_.blade_slides;
  }
}

void SubdivisionCutter::presplit_generic(const Contact& contact) {
  // The cut tetrahedra of this move whose originals have not had the generic split yet, by
  // their vertices (ids of tetrahedra change while splitting).
  std::vector<Tet> chosen;
  std::map<std::pair<VertexId, VertexId>, double> crossing_at;
  for (const Crossing& crossing : contact.crossings) {
    const bool forward = crossing.a < crossing.b;
    crossing_at[{std::min(crossing.a, crossing.b), std::max(crossing.a, crossing.b)}] =
        forward ? crossing.t : 1.0 - crossing.t;
  }
  for (TetId t : contact.touched) {
    const Tet& v = mesh_.tet(t);
    bool crossed = false;
    for (const auto& e : tet_local::kEdges) {
      crossed =
          crossed || crossing_at.contains({std::min(v[e[0]], v[e[1]]), std::max(v[e[0]], v[e[1]])});
    }
    const auto id = static_cast<std::size_t>(ancestry(t).id);
    if (crossed && ancestor_presplit_[id] == 0) {
      ancestor_presplit_[id] = 1;
      chosen.push_back(v);
      ++stats_.generic_splits;
    }
  }
  // Every edge: at the crossing, else at its midpoint.
  std::map<std::pair<VertexId, VertexId>, VertexId> node;
  for (const Tet& v : chosen) {
    for (const auto& e : tet_local::kEdges) {
      const std::pair key{std::min(v[e[0]], v[e[1]]), std::max(v[e[0]], v[e[1]])};
      const EdgeId edge = mesh_.find_edge(key.first, key.second);
      if (edge == kInvalidId) {
        continue;  // split already, for a neighbour
      }
      const auto crossing = crossing_at.find(key);
      const double from_low = crossing != crossing_at.end() ? crossing->second : 0.5;
      const double t = mesh_.edge(edge)[0] == key.first ? from_low : 1.0 - from_low;
      const VertexId middle = split_edge(mesh_, edge, t);
      node[key] = middle;
      if (crossing != crossing_at.end()) {
        mark_on_cut(middle, 0.0);
      }
      ++stats_.edges_split;
      stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, std::min(t, 1.0 - t));
    }
  }
  // Every face: at the centroid of the largest of the triangles it now consists of.
  std::vector<std::array<VertexId, 3>> faces;
  for (const Tet& v : chosen) {
    for (int f = 0; f < 4; ++f) {
      faces.push_back(face_key(v, f));
    }
  }
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  for (const auto& face : faces) {
    std::vector<VertexId> members(face.begin(), face.end());
    for (int i = 0; i < 3; ++i) {
      const auto it = node.find(std::minmax(face[i], face[(i + 1) % 3]));
      if (it != node.end()) {
        members.push_back(it->second);
      }
    }
    std::sort(members.begin(), members.end());
    const auto member = [&](VertexId x) {
      return std::binary_search(members.begin(), members.end(), x);
    };
    TetId best_tet = kInvalidId;
    int best_face = -1;
    double best_area = 0.0;
    for (VertexId x : members) {
      for (TetId t : mesh_.vertex_tets(x)) {
        const Tet& v = mesh_.tet(t);
        for (int f = 0; f < 4; ++f) {
          const auto& local = tet_local::kFaces[f];
          if (!member(v[local[0]]) || !member(v[local[1]]) || !member(v[local[2]])) {
            continue;
          }
          const double area = (position(v[local[1]]) - position(v[local[0]]))
                                  .cross(position(v[local[2]]) - position(v[local[0]]))
                                  .norm();
          if (area > best_area) {
            best_area = area;
            best_tet = t;
            best_face = f;
          }
        }
      }
    }
    if (best_tet != kInvalidId) {
      (void)split_face(mesh_, best_tet, best_face, {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0});
      stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, 1.0 / 3.0);
    }
  }
}

double SubdivisionCutter::distance_to_move(const Vec3& rest_point) const {
  return distance_to(move_rest_triangles_, rest_point);
}

bool SubdivisionCutter::parts_across_surface(TetId tet, int local_face, TetId neighbor) const {
  const Tet& v = mesh_.tet(tet);
  const auto& face = tet_local::kFaces[local_face];
  const std::array<VertexId, 3> corners{v[face[0]], v[face[1]], v[face[2]]};
  const std::array<Vec3, 3> p = rest_face(mesh_, tet, local_face);
  // Round-off allowance: points computed on the surface lie on it only up to this (m).
  const double round_off = 1e-9 * longest_edge(p);
  // On the surface: every corner as close to it as when it was put on the cut, and the
  // centroid too (so a face bridging two separate sheets of the surface is not taken).
  double allowed = 0.0;
  for (std::size_t k = 0; k < 3; ++k) {
    const double offset = cut_offset_[corners[k]];
    if (!swept_->any_within(p[k], offset * (1.0 + 1e-9) + round_off)) {
      return false;
    }
    allowed = std::max(allowed, offset);
  }
  const std::int64_t nearest =
      swept_->nearest(centroid(p), allowed * (1.0 + 1e-9) + round_off, nullptr);
  if (nearest < 0) {
    return false;
  }
  // Sides: each tetrahedron is on the side of its centroid (one side per tetrahedron, so a flat
  // one whose corners all lie on the cut joins one side and is not cut out of both; a thin
  // region that still falls between cut faces is given back to one side by keep_no_shards).
  const auto& plane = swept_->triangle(static_cast<std::size_t>(nearest));
  return side_of(centroid(rest_corners(mesh_, tet)), plane) !=
         side_of(centroid(rest_corners(mesh_, neighbor)), plane);
}

std::vector<VertexId> SubdivisionCutter::mark_cut_faces() {
  std::sort(fresh_.begin(), fresh_.end());
  fresh_.erase(std::unique(fresh_.begin(), fresh_.end()), fresh_.end());
  std::vector<VertexId> corners;
  marked_.clear();
  std::set<std::array<VertexId, 3>> seen;
  for (VertexId x : fresh_) {
    for (TetId t : mesh_.vertex_tets(x)) {
      const Tet& v = mesh_.tet(t);
      for (int f = 0; f < 4; ++f) {
        const TetId neighbor = mesh_.tet_neighbors(t)[f];
        // Every interior face of the tetrahedra around x, the face opposite x too: x may be a
        // new corner that moved the tetrahedron's centroid to the other side. The neighbour
        // across need not contain x, so a face is taken from whichever side sees it first.
        if (neighbor < 0 || marks_.is_cut(t, f)) {
          continue;
        }
        const auto& face = tet_local::kFaces[f];
        if (on_cut_[v[face[0]]] == 0 || on_cut_[v[face[1]]] == 0 || on_cut_[v[face[2]]] == 0 ||
            !seen.insert(face_key(v, f)).second || !parts_across_surface(t, f, neighbor)) {
          continue;
        }
        marks_.mark(t, f);
        marked_.emplace_back(t, f);
        ++stats_.cut_faces;
        stats_.cut_area += area(rest_face(mesh_, t, f));
        corners.insert(corners.end(), {v[face[0]], v[face[1]], v[face[2]]});
      }
    }
  }
  keep_no_shards();
  return corners;
}

void SubdivisionCutter::keep_no_shards() {
  // Regions closed off by cut faces are found by a bounded walk across faces that are not cut:
  // a walk that grows past the budget is in a large piece (and so is every tetrahedron it saw).
  constexpr std::size_t kBudget = 256;
  std::unordered_set<TetId> large;
  std::unordered_set<TetId> checked;
  std::vector<TetId> region;
  std::unordered_set<TetId> inside;
  for (const auto& [tet, face] : marked_) {
    const TetId across = mesh_.tet_neighbors(tet)[face];
    for (TetId start : {tet, across}) {
      if (start < 0 || large.contains(start) || checked.contains(start)) {
        continue;
      }
      region.assign(1, start);
      inside = {start};
      bool closed = true;
      for (std::size_t k = 0; k < region.size() && closed; ++k) {
        for (int g = 0; g < 4 && closed; ++g) {
          const TetId other = mesh_.tet_neighbors(region[k])[g];
          if (other < 0 || marks_.is_cut(region[k], g) || inside.contains(other)) {
            continue;
          }
          if (large.contains(other) || region.size() >= kBudget) {
            closed = false;
          } else {
            inside.insert(other);
            region.push_back(other);
          }
        }
      }
      if (!closed) {
        large.insert(region.begin(), region.end());
        continue;
      }
      checked.insert(region.begin(), region.end());
      // Its thickness across the cut, against the snap distance of its tetrahedra.
      double volume = 0.0;
      double cut_area = 0.0;
      double longest = 0.0;
      std::array<double, 2> shared_area{0.0, 0.0};  // still joined to the - and + side
      for (TetId r : region) {
        volume += std::abs(signed_volume(mesh_, r));
        longest = std::max(longest, longest_edge(rest_corners(mesh_, r)));
        for (int g = 0; g < 4; ++g) {
          if (!marks_.is_cut(r, g)) {
            continue;
          }
          const std::array<Vec3, 3> corners = rest_face(mesh_, r, g);
          const double face_area = area(corners);
          cut_area += face_area;
          const TetId other = mesh_.tet_neighbors(r)[g];
          if (other >= 0) {
            shared_area[swept_side(other, centroid(corners), face_reach(r, g)) < 0 ? 0 : 1] +=
                face_area;
          }
        }
      }
      if (cut_area == 0.0 || volume >= options_.snap_fraction * longest * cut_area) {
        continue;
      }
      const int join = shared_area[0] >= shared_area[1] ? -1 : 1;
      if (shared_area[join < 0 ? 0 : 1] == 0.0) {
        continue;  // no longer joined to either side: nothing to give back
      }
      for (TetId r : region) {
        for (int g = 0; g < 4; ++g) {
          const TetId other = mesh_.tet_neighbors(r)[g];
          if (other >= 0 && marks_.is_cut(r, g) && !inside.contains(other)) {
            if (swept_side(other, centroid(rest_face(mesh_, r, g)), face_reach(r, g)) == join) {
              marks_.unmark(r, g);
              ++stats_.shards_kept;
            }
          }
        }
      }
    }
  }
}

double SubdivisionCutter::face_reach(TetId tet, int local_face) const {
  const Tet& v = mesh_.tet(tet);
  const auto& face = tet_local::kFaces[local_face];
  double offset = 0.0;
  for (int k = 0; k < 3; ++k) {
    offset = std::max(offset, cut_offset_[v[face[k]]]);
  }
  return offset * (1.0 + 1e-9) + 1e-9 * longest_edge(rest_face(mesh_, tet, local_face));
}

int SubdivisionCutter::swept_side(TetId tet, const Vec3& near_point, double radius) const {
  const std::array<Vec3, 4> corners = rest_corners(mesh_, tet);
  const std::int64_t nearest = swept_->nearest(near_point, radius, nullptr);
  if (nearest < 0) {
    return 0;
  }
  return side_of(centroid(corners), swept_->triangle(static_cast<std::size_t>(nearest)));
}

void SubdivisionCutter::move_to(const BladePose& pose) {
  if (!started_) {
    start(pose);
    return;
  }
  BladePose from = pose_;
  if (positions_ != nullptr) {
    from.tip = current(tip_material_, from.tip);
    from.base = current(base_material_, from.base);
  }
  pose_ = pose;
  ++stats_.moves;
  const auto triangles = swept_triangles(from, pose);
  for (const auto& triangle : triangles) {
    stats_.swept_area += area(triangle);
  }
  fresh_.clear();
  move_triangles_ = triangles;

  // ---- the blade line: vertices where it crosses faces, and at its tip ---------------------
  auto start = Clock::now();
  if (positions_moved_) {
    grid_.refit();  // the body moved since the last cut
    positions_moved_ = false;
  }
  if (options_.open_under_blade && !triangles.empty()) {
    // Both ends of the swept surface: the previous blade line was inserted by the previous
    // move already (unless the body moved since or this is the first move).
    const auto unit_normal = [](const std::array<Vec3, 3>& t) {
      return (t[1] - t[0]).cross(t[2] - t[0]).normalized();
    };
    if (provisional_.empty()) {
      insert_blade_points(from, unit_normal(triangles.front()));
    }
    next_provisional_.clear();
    sliding_ = options_.slide_blade_points;
    if (sliding_) {
      slide_blade_points(pose);
    }
    insert_blade_points(pose, unit_normal(triangles.back()));
    sliding_ = false;
  }
  provisional_.clear();
  double gc_seconds = seconds_since(start);

  // ---- collision detection: tets the swept surface touches, edges it crosses ---------------
  start = Clock::now();
  Contact contact = detect(triangles);
  stats_.candidate_tets = contact.touched.size();
  record_swept(triangles, contact);
  classify(contact, pose);
  stats_.cd_seconds = seconds_since(start);
  if (options_.split == SplitMode::kGeneric && !contact.crossings.empty()) {
    start = Clock::now();
    presplit_generic(contact);
    gc_seconds += seconds_since(start);
    start = Clock::now();
    contact = detect(triangles);
    stats_.cd_seconds += seconds_since(start);
  }

  // ---- topology and geometry changes ---------------------------------------------------------
  start = Clock::now();
  for (VertexId v : contact.snapped) {
    if (on_cut_[v] == 0) {
      mark_on_cut(v, distance_to_move(mesh_.rest_position(v)));
      ++stats_.vertices_snapped;
    }
    fresh_.push_back(v);  // met by this move: faces through it are decided again
  }
  for (const Crossing& crossing : contact.crossings) {
    if (on_cut_[crossing.a] != 0 && on_cut_[crossing.b] != 0) {
      continue;  // both ends already on the cut: the crossing is the cut itself
    }
    const EdgeId edge = mesh_.find_edge(crossing.a, crossing.b);
    INCISE_ASSERT(edge != kInvalidId, "a crossed edge vanished before it was split");
    const double t = mesh_.edge(edge)[0] == crossing.a ? crossing.t : 1.0 - crossing.t;
    const VertexId middle = split_edge(mesh_, edge, t);
    mark_on_cut(middle, 0.0);
    ++stats_.edges_split;
    stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, std::min(t, 1.0 - t));
  }
  surface_.insert(surface_.end(), triangles.begin(), triangles.end());

  // Open the cut: decide the faces this move puts on it, then separate their corners where
  // cut faces part the tetrahedra around them. Faces through vertices put on the cut earlier
  // are decided again where this move swept: the surface may only now reach past them.
  for (const auto& triangle : triangles) {
    Vec3 low;
    Vec3 high;
    triangle_bounds(triangle, low, high);
    const Vec3 margin = Vec3::Constant(grid_.cell_size() * 0.5);
    grid_.query(low - margin, high + margin, scratch_);
    for (TetId t : scratch_) {
      for (VertexId v : mesh_.tet(t)) {
        if (on_cut_[v] != 0) {
          fresh_.push_back(v);
        }
      }
    }
  }
  std::vector<VertexId> candidates = mark_cut_faces();
  // Vertices on the cut where this move swept may be pinched or separable too.
  candidates.insert(candidates.end(), fresh_.begin(), fresh_.end());
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
  // Blade-line vertices the cut has opened at stay where they are.
  std::sort(separated_.begin(), separated_.end());
  for (const Provisional& point : next_provisional_) {
    if (!std::binary_search(separated_.begin(), separated_.end(), point.vertex)) {
      provisional_.push_back(point);
    }
  }
  separated_.clear();
  stats_.gc_seconds = gc_seconds + seconds_since(start);
  stats_.total_cd_seconds += stats_.cd_seconds;
  stats_.total_gc_seconds += stats_.gc_seconds;
  stats_.max_move_seconds =
      std::max(stats_.max_move_seconds, stats_.cd_seconds + stats_.gc_seconds);

  track_point_tet();
  update_active_tets();
  if (positions_ != nullptr) {
    tip_material_ = material_point(pose.tip);
    base_material_ = material_point(pose.base);
  }
}

void SubdivisionCutter::save_state(StateWriter& out) const {
  out.tag("subdivision cutter");
  out.value(pose_);
  out.value(started_);
  out.value(positions_moved_);
  out.value(point_tet_);
  out.value(tip_material_);
  out.value(base_material_);
  out.value(stats_);
  out.values(active_);
  out.values(provisional_);
  out.values(move_triangles_);
  out.values(move_rest_triangles_);
  out.values(surface_);
  out.values(ancestor_codes_);
  out.values(ancestor_presplit_);
  swept_->save_state(out);
}

void SubdivisionCutter::load_state(StateReader& in) {
  in.tag("subdivision cutter");
  pose_ = in.value<BladePose>("blade pose");
  started_ = in.value<bool>("stroke started");
  positions_moved_ = in.value<bool>("positions moved");
  point_tet_ = in.value<TetId>("tip tetrahedron");
  tip_material_ = in.value<MaterialPoint>("tip material point");
  base_material_ = in.value<MaterialPoint>("base material point");
  stats_ = in.value<CutStats>("cut statistics");
  active_ = in.values<TetId>("active tetrahedra");
  provisional_ = in.values<Provisional>("blade-line vertices");
  move_triangles_ = in.values<std::array<Vec3, 3>>("last swept triangles");
  move_rest_triangles_ = in.values<std::array<Vec3, 3>>("last swept triangles at rest");
  surface_ = in.values<std::array<Vec3, 3>>("swept surface");
  ancestor_codes_ = in.values<std::uint8_t>("cut-edge codes");
  ancestor_presplit_ = in.values<char>("generic splits");
  swept_->load_state(in);
  const auto tets = static_cast<TetId>(mesh_.tet_count());
  const auto vertices = static_cast<VertexId>(mesh_.vertex_count());
  bool ok = point_tet_ >= kInvalidId && point_tet_ < tets;
  for (TetId t : active_) {
    ok = ok && t >= 0 && t < tets;
  }
  for (const Provisional& p : provisional_) {
    ok = ok && p.vertex >= 0 && p.vertex < vertices && p.count >= 3 && p.count <= 4;
    for (int k = 0; k < p.count; ++k) {
      ok = ok && p.corners[static_cast<std::size_t>(k)] >= 0 &&
           p.corners[static_cast<std::size_t>(k)] < vertices;
    }
  }
  if (!ok) {
    in.fail("the cutter", "it names tetrahedra or vertices the mesh does not have");
  }
  fresh_.clear();
  separated_.clear();
  next_provisional_.clear();
}

}  // namespace incise
