// Vertices on the blade line: inserted where it crosses faces and at its tip, left out where
// they would thin a tetrahedron, and slid along with the blade at the next pose.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <set>
#include <vector>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "parallel_tests.hpp"
#include "triangle_index.hpp"

namespace incise {

using namespace cutter_detail;  // NOLINT(google-build-using-namespace): the cutter's own helpers

void SubdivisionCutter::insert_blade_points(const BladePose& pose, const Vec3& normal) {
  // Where the blade line enters and leaves each tetrahedron it passes through (and its tip or
  // base where they are inside), as parameters from the tip (0) to the base (1).
  const Vec3 direction = pose.base - pose.tip;
  if (direction.squaredNorm() == 0.0) {
    return;
  }
  grid_.query(pose.tip.cwiseMin(pose.base), pose.tip.cwiseMax(pose.base), scratch_);
  struct Passage {
    double enter = 0.0;
    double leave = -1.0;  // leave < enter: the blade line does not pass through
  };
  std::vector<Passage> passages;
  test_each<TetId>(scratch_, passages, [&](TetId t) {
    const Tet& v = mesh_.tet(t);
    const std::array<Vec3, 4> p{position(v[0]), position(v[1]), position(v[2]), position(v[3])};
    if (!segment_intersects_tet(pose.tip, pose.base, p[0], p[1], p[2], p[3])) {
      return Passage{};
    }
    Passage passage{0.0, 1.0};
    for (int f = 0; f < 4; ++f) {
      const auto& face = tet_local::kFaces[f];
      Vec3 inward = (p[face[1]] - p[face[0]]).cross(p[face[2]] - p[face[0]]);
      if (inward.dot(p[f] - p[face[0]]) < 0.0) {
        inward = -inward;  // towards the opposite vertex
      }
      const double at_tip = inward.dot(pose.tip - p[face[0]]);
      const double rate = inward.dot(direction);
      if (rate > 0.0) {
        passage.enter = std::max(passage.enter, -at_tip / rate);
      } else if (rate < 0.0) {
        passage.leave = std::min(passage.leave, -at_tip / rate);
      }
    }
    return passage.enter <= passage.leave ? passage : Passage{};
  });
  std::vector<double> parameters;
  for (const Passage& passage : passages) {
    if (passage.enter <= passage.leave) {
      parameters.push_back(passage.enter);
      parameters.push_back(passage.leave);
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

double SubdivisionCutter::cut_area_through(std::initializer_list<VertexId> vertices) const {
  // As cut_area_around, over the faces through any of the vertices, each (tetrahedron, face)
  // once.
  std::vector<TetId> tets;
  for (VertexId vertex : vertices) {
    tets.insert(tets.end(), mesh_.vertex_tets(vertex).begin(), mesh_.vertex_tets(vertex).end());
  }
  std::sort(tets.begin(), tets.end());
  tets.erase(std::unique(tets.begin(), tets.end()), tets.end());
  double total = 0.0;
  for (TetId t : tets) {
    const Tet& v = mesh_.tet(t);
    for (int f = 0; f < 4; ++f) {
      bool through = false;
      for (VertexId vertex : vertices) {
        through = through || (v[f] != vertex && std::find(v.begin(), v.end(), vertex) != v.end());
      }
      if (through && marks_.is_cut(t, f)) {
        total += 0.5 * area(rest_face(mesh_, t, f));
      }
    }
  }
  return total;
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
  std::vector<std::pair<Provisional, std::array<double, 4>>> leaving;

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
      // The blade is leaving the face or tetrahedron: the vertex is handed over to where the
      // cut will cross the face's edge, or stays behind, to be collapsed onto the crossing
      // this move makes if it can (collapse_left_behind).
      if (point.count == 3) {
        leaving.emplace_back(point, weights);
      } else {
        left_behind_.push_back(point);
      }
      continue;
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
    double star_before = 0.0;  // m^3, rest
    double star_after = 0.0;
    // Where the simulation has the body, the vertex moves to the same combination.
    Vec3 deformed = Vec3::Zero();
    if (deformed_ != nullptr) {
      for (int k = 0; k < point.count; ++k) {
        deformed += weights[k] * (*deformed_)[point.corners[k]];
      }
    }
    const auto cutter_position = [this](VertexId u) { return position(u); };
    const auto simulated_position = [this](VertexId u) { return (*deformed_)[u]; };
    for (TetId t : mesh_.vertex_tets(vertex)) {
      const int local = mesh_.local_index(t, vertex);
      const std::array<Vec3, 4> before = rest_corners(mesh_, t);
      std::array<Vec3, 4> after = before;
      after[local] = rest;
      star_before += signed_volume(before[0], before[1], before[2], before[3]);
      star_after += signed_volume(after[0], after[1], after[2], after[3]);
      ok = orient3d(after[0], after[1], after[2], after[3]) == Sign::kPositive &&
           quality(after) >= slide_floor(quality(before));
      ok = ok && (positions_ == nullptr ||
                  positive_with_corner_at(mesh_, t, local, now, cutter_position));
      ok = ok && (deformed_ == nullptr ||
                  positive_with_corner_at(mesh_, t, local, deformed, simulated_position));
      if (!ok) {
        break;
      }
    }
    // Inside its face or tetrahedron, the tetrahedra around it fill the same star wherever it
    // moves (all stay positive), so volume and boundary are kept; except where the cut has
    // opened around it without separating it (its lips meet there, as on the crack front) and
    // the blade has turned: the move would tilt the open faces and change the body's volume
    // (found by incise soak, tests/data/soak_findings). Such a vertex stays.
    ok = ok && std::abs(star_after - star_before) <= 1e-10 * star_before;
    if (!ok) {
      continue;
    }
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
  hand_over(leaving);
}

namespace {

/// How many of `corners` (the first `count`) `vertex` was made from, through edge, face and
/// tetrahedron splits, copies and slides (its vertex origins, not its coordinates): 1 for a
/// corner or a point made from one, 2 for a point on an edge between two of them, ...; -1 when
/// it depends on another vertex (or on too long a history to follow).
int corners_spanned(const TetMesh& mesh, VertexId vertex, const std::array<VertexId, 4>& corners,
                    int count) {
  std::vector<VertexId> leaves;
  std::vector<VertexId> stack{vertex};
  const auto is_corner = [&](VertexId v) {
    return std::find(corners.begin(), corners.begin() + count, v) != corners.begin() + count;
  };
  for (int steps = 0; !stack.empty(); ++steps) {
    if (steps > 256) {
      return -1;
    }
    const VertexId v = stack.back();
    stack.pop_back();
    if (is_corner(v)) {
      leaves.push_back(v);
      continue;
    }
    const VertexOrigin& origin = mesh.vertex_origin(v);
    if (origin.kind == VertexOrigin::Kind::kFresh) {
      return -1;  // an original vertex that is not a corner
    }
    for (int p = 0; p < origin.parent_count; ++p) {
      if (origin.weights[static_cast<std::size_t>(p)] > 0.0) {
        stack.push_back(origin.parents[static_cast<std::size_t>(p)]);
      }
    }
  }
  std::sort(leaves.begin(), leaves.end());
  return static_cast<int>(std::unique(leaves.begin(), leaves.end()) - leaves.begin());
}

/// Whether `vertex` lies on the boundary of the feature spanned by `corners` (a face's three
/// or a tetrahedron's four): it was made from fewer of them than the feature has.
bool on_feature_boundary(const TetMesh& mesh, VertexId vertex,
                         const std::array<VertexId, 4>& corners, int count) {
  const int spanned = corners_spanned(mesh, vertex, corners, count);
  return spanned >= 0 && spanned < count;
}

}  // namespace

namespace {

/// Whether the boundary faces through `vertex` lie in one plane (their areas add up to the
/// area of their sum, to round-off).
bool flat_boundary_fan(const TetMesh& mesh, VertexId vertex) {
  Vec3 vector = Vec3::Zero();
  double total = 0.0;
  for (TetId t : mesh.vertex_tets(vertex)) {
    const int local = mesh.local_index(t, vertex);
    for (int f = 0; f < 4; ++f) {
      if (f != local && mesh.tet_neighbors(t)[f] < 0) {
        const std::array<Vec3, 3> face = rest_face(mesh, t, f);
        const Vec3 normal = (face[1] - face[0]).cross(face[2] - face[0]);
        vector += normal;
        total += normal.norm();
      }
    }
  }
  return std::abs(total - vector.norm()) <= 1e-9 * total;
}

/// Whether the cut has opened at `vertex`: a face through it is a boundary face the cut made.
bool opened_at(const TetMesh& mesh, const CutFaceMarks& marks, VertexId vertex) {
  for (TetId t : mesh.vertex_tets(vertex)) {
    const int local = mesh.local_index(t, vertex);
    for (int f = 0; f < 4; ++f) {
      if (f != local && mesh.tet_neighbors(t)[f] < 0 && marks.is_cut(t, f)) {
        return true;
      }
    }
  }
  return false;
}

}  // namespace

bool SubdivisionCutter::boundary_kept_flat(VertexId vertex, VertexId target) const {
  // The boundary faces through the vertex (the cut's, once it has opened there) lie in one
  // plane, the target in it: collapsing retriangulates that flat piece of boundary, with the
  // same area and the same shape, so each side's copy of the wound keeps matching the other.
  Vec3 vector_before = Vec3::Zero();
  Vec3 vector_after = Vec3::Zero();
  double area_before = 0.0;
  double area_after = 0.0;
  for (TetId t : mesh_.vertex_tets(vertex)) {
    const int local = mesh_.local_index(t, vertex);
    const bool removed = mesh_.local_index(t, target) >= 0;
    for (int f = 0; f < 4; ++f) {
      if (f == local || mesh_.tet_neighbors(t)[f] >= 0) {
        continue;
      }
      std::array<Vec3, 3> face = rest_face(mesh_, t, f);
      const Vec3 normal = (face[1] - face[0]).cross(face[2] - face[0]);
      vector_before += normal;
      area_before += normal.norm();
      const Tet& v = mesh_.tet(t);
      const auto& corners = tet_local::kFaces[f];
      bool through_target = false;
      for (int k = 0; k < 3; ++k) {
        through_target = through_target || v[corners[k]] == target;
        if (v[corners[k]] == vertex) {
          face[k] = mesh_.rest_position(target);
        }
      }
      if (removed && through_target) {
        continue;  // collapses to an edge
      }
      const Vec3 moved = (face[1] - face[0]).cross(face[2] - face[0]);
      vector_after += moved;
      area_after += moved.norm();
    }
  }
  const double tolerance = 1e-9 * area_before;
  return std::abs(area_before - vector_before.norm()) <= tolerance &&
         std::abs(area_after - area_before) <= tolerance &&
         (vector_after - vector_before).norm() <= tolerance;
}

bool SubdivisionCutter::try_collapse(VertexId vertex, VertexId target) {
  // A target the cut has opened at (its copies hold the two sides apart) would join the sides
  // again through the vertex's tetrahedra, which hold both, unless the cut has opened at the
  // vertex too (its tetrahedra lie on one side).
  const bool opened = opened_at(mesh_, marks_, vertex);
  if (opened_at(mesh_, marks_, target) && !opened) {
    return false;
  }
  if (opened && !boundary_kept_flat(vertex, target)) {
    return false;
  }
  // Every tetrahedron that stays is positive (at rest and where the cutter intersects) and its
  // worst no worse than the star's worst (or than 0.05). Each original tetrahedron's part of
  // the star keeps its volume, and a removed tetrahedron is absorbed by one of the same
  // original: so the body's boundary, every region and material (given per original), and
  // the mass of each are kept.
  const std::span<const TetId> star = mesh_.vertex_tets(vertex);
  double worst_before = 1.0;
  double worst_after = 1.0;
  double star_volume = 0.0;
  std::vector<std::pair<std::int32_t, double>> change;  // (original, m^3 after - before)
  for (TetId t : star) {
    const std::array<Vec3, 4> before = rest_corners(mesh_, t);
    const std::int32_t original = ancestry_[t].id;
    const double volume = signed_volume(before[0], before[1], before[2], before[3]);
    worst_before = std::min(worst_before, quality(before));
    star_volume += volume;
    change.emplace_back(original, -volume);
    const int at_target = mesh_.local_index(t, target);
    if (at_target >= 0) {
      const TetId absorber = mesh_.tet_neighbors(t)[at_target];
      if (absorber < 0 || ancestry_[absorber].id != original) {
        return false;
      }
      continue;  // removed
    }
    const int local = mesh_.local_index(t, vertex);
    std::array<Vec3, 4> after = before;
    after[local] = mesh_.rest_position(target);
    if (orient3d(after[0], after[1], after[2], after[3]) != Sign::kPositive) {
      return false;
    }
    // ... and where the cutter intersects, and where the simulation has the body.
    if (positions_ != nullptr &&
        !positive_with_corner_at(mesh_, t, local, position(target),
                                 [this](VertexId u) { return position(u); })) {
      return false;
    }
    if (deformed_ != nullptr &&
        !positive_with_corner_at(mesh_, t, local, (*deformed_)[target],
                                 [this](VertexId u) { return (*deformed_)[u]; })) {
      return false;
    }
    worst_after = std::min(worst_after, quality(after));
    change.emplace_back(original, signed_volume(after[0], after[1], after[2], after[3]));
  }
  if (worst_after < std::min(0.05, worst_before)) {
    return false;
  }
  std::sort(change.begin(), change.end());
  for (std::size_t k = 0; k < change.size();) {
    double sum = 0.0;
    const std::int32_t original = change[k].first;
    for (; k < change.size() && change[k].first == original; ++k) {
      sum += change[k].second;
    }
    if (std::abs(sum) > 1e-10 * star_volume) {
      return false;
    }
  }
  const double area_before = cut_area_through({vertex, target});
  try {
    mesh_.collapse_vertex(vertex, target);
  } catch (const InputError&) {
    return false;  // the link condition does not hold here: the vertex stays
  }
  // Interior faces through the target are decided again, as for any vertex this move put on
  // the cut (those through the collapsed vertex now run through it). Faces the cut opened keep
  // their marks.
  for (TetId t : mesh_.vertex_tets(target)) {
    const Tet& v = mesh_.tet(t);
    const int local = mesh_.local_index(t, target);
    for (int f = 0; f < 4; ++f) {
      const TetId neighbor = mesh_.tet_neighbors(t)[f];
      if (f == local || neighbor < 0) {
        continue;
      }
      const auto& face = tet_local::kFaces[f];
      const int across = local_face_of(mesh_.tet(neighbor), v[face[0]], v[face[1]], v[face[2]]);
      marks_.unmark(t, f);
      if (across >= 0) {
        marks_.unmark(neighbor, across);
      }
    }
  }
  stats_.cut_area += cut_area_through({target}) - area_before;
  fresh_.push_back(target);
  ++stats_.blade_points_collapsed;
  return true;
}

std::optional<SubdivisionCutter::Handover> SubdivisionCutter::exit_of(
    const Provisional& point, const std::array<double, 4>& next) const {
  // The trace of the swept surface in the face runs from the vertex (weights `now`) towards
  // where the new blade line meets the face's plane (`next`), which is within the snap
  // fraction of the face's boundary or past it; it leaves through the side whose weight
  // reaches 0 first.
  const VertexId vertex = point.vertex;
  std::array<Vec3, 3> feature;
  for (int k = 0; k < 3; ++k) {
    feature[k] = position(point.corners[k]);
  }
  const Vec3 normal = (feature[1] - feature[0]).cross(feature[2] - feature[0]);
  const double area2 = normal.squaredNorm();
  if (!(area2 > 0.0) || mesh_.vertex_tets(vertex).empty()) {
    return std::nullopt;
  }
  const Vec3 at = position(vertex);
  const std::array<double, 3> now{normal.dot((feature[1] - at).cross(feature[2] - at)) / area2,
                                  normal.dot((feature[2] - at).cross(feature[0] - at)) / area2,
                                  normal.dot((feature[0] - at).cross(feature[1] - at)) / area2};
  double leave = std::numeric_limits<double>::infinity();
  int side = -1;
  for (int k = 0; k < 3; ++k) {
    if (next[k] < now[k] && next[k] < options_.snap_fraction) {
      const double s = now[k] / (now[k] - next[k]);
      if (s >= 0.0 && s < leave) {
        leave = s;
        side = k;
      }
    }
  }
  if (side < 0) {
    return std::nullopt;
  }
  std::array<double, 3> exit{};
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    exit[k] = k == side ? 0.0 : std::max(0.0, now[k] + leave * (next[k] - now[k]));
    sum += exit[k];
  }
  if (!(sum > 0.0)) {
    return std::nullopt;
  }
  // The exit may lie ahead of the blade, by at most the snap distance of the face (measured
  // where the cutter intersects, as this move's swept triangles).
  Vec3 exit_point = Vec3::Zero();
  double size = 0.0;
  for (int k = 0; k < 3; ++k) {
    exit_point += exit[k] / sum * feature[k];
    size = std::max(size, (feature[k] - feature[(k + 1) % 3]).norm());
  }
  Handover handover;
  handover.vertex = vertex;
  handover.a = point.corners[static_cast<std::size_t>((side + 1) % 3)];
  handover.b = point.corners[static_cast<std::size_t>((side + 2) % 3)];
  handover.t = exit[static_cast<std::size_t>((side + 2) % 3)] / sum;  // from a to b
  handover.ahead = distance_to(move_triangles_, exit_point);
  handover.size = size;
  if (handover.ahead > options_.snap_fraction * size) {
    return std::nullopt;
  }
  return handover;
}

VertexId SubdivisionCutter::vertex_at_exit(const Handover& exit) {
  // The vertices on the edge (a, b) next to the leaving vertex, by their place along it: the
  // edge may have been split already (by a crossing, or by the exit of a blade-line vertex in
  // a neighbouring face, which leaves through the same point).
  const Vec3 from = mesh_.rest_position(exit.a);
  const Vec3 along = mesh_.rest_position(exit.b) - from;
  const double length2 = along.squaredNorm();
  if (!(length2 > 0.0)) {
    return kInvalidId;
  }
  std::vector<std::pair<double, VertexId>> chain{{0.0, exit.a}, {1.0, exit.b}};
  const std::array<VertexId, 4> ends{exit.a, exit.b, kInvalidId, kInvalidId};
  for (TetId t : mesh_.vertex_tets(exit.vertex)) {
    for (VertexId u : mesh_.tet(t)) {
      if (u != exit.a && u != exit.b && u != exit.vertex &&
          corners_spanned(mesh_, u, ends, 2) > 0) {
        chain.emplace_back((mesh_.rest_position(u) - from).dot(along) / length2, u);
      }
    }
  }
  std::sort(chain.begin(), chain.end());
  chain.erase(std::unique(chain.begin(), chain.end()), chain.end());
  // The nearest vertex on the edge, if the exit is within the snap fraction of the piece of
  // edge it lies on; else that piece is split at the exit.
  for (std::size_t k = 0; k + 1 < chain.size(); ++k) {
    const auto [t0, p] = chain[k];
    const auto [t1, q] = chain[k + 1];
    if (exit.t < t0 || exit.t > t1) {
      continue;
    }
    const double piece = t1 - t0;
    if (!(piece > 0.0)) {
      return kInvalidId;
    }
    const double within = (exit.t - t0) / piece;
    if (within < options_.snap_fraction) {
      return p;
    }
    if (within > 1.0 - options_.snap_fraction) {
      return q;
    }
    const EdgeId edge = mesh_.find_edge(p, q);
    if (edge == kInvalidId) {
      return kInvalidId;  // the chain misses a vertex the leaving vertex does not see
    }
    const VertexId made = split_edge(mesh_, edge, mesh_.edge(edge)[0] == p ? within : 1.0 - within);
    ++stats_.edges_split;
    return made;
  }
  return kInvalidId;
}

void SubdivisionCutter::hand_over(
    const std::vector<std::pair<Provisional, std::array<double, 4>>>& leaving) {
  // A blade-line vertex in a face the blade is leaving is collapsed onto the point where the
  // cut will cross the face's edge (split there, or a vertex on the edge within the snap
  // fraction): the face keeps no vertex of its own. The blade line leaves neighbouring faces
  // through the same point at once, and one vertex's collapse may need another's first, so
  // collapses are tried again while any succeeds.
  std::vector<std::pair<VertexId, VertexId>> pending;  // (vertex, target)
  for (const auto& [point, next] : leaving) {
    const auto exit = exit_of(point, next);
    const VertexId target = exit ? vertex_at_exit(*exit) : kInvalidId;
    if (target == kInvalidId) {
      left_behind_.push_back(point);
      continue;
    }
    if (on_cut_[target] == 0) {
      // On the swept surface ahead of the blade, or a vertex within the snap fraction of it.
      mark_on_cut(target, std::max({1e-9 * exit->size, exit->ahead,
                                    distance_to(move_triangles_, position(target))}));
    } else {
      fresh_.push_back(target);
    }
    pending.emplace_back(point.vertex, target);
  }
  for (bool progress = true; progress && !pending.empty();) {
    progress = false;
    for (auto it = pending.begin(); it != pending.end();) {
      if (mesh_.find_edge(it->first, it->second) != kInvalidId &&
          try_collapse(it->first, it->second)) {
        it = pending.erase(it);
        progress = true;
      } else {
        ++it;
      }
    }
  }
}

bool SubdivisionCutter::collapse_opened_behind(const std::vector<TetId>& around) {
  // Vertices made inside a face (the blade line's points) and their copies, on the cut, each
  // with the face point it is (itself, or the vertex it copies).
  std::vector<std::pair<VertexId, VertexId>> points;  // (vertex, face point)
  for (TetId t : around) {
    for (VertexId v : mesh_.tet(t)) {
      if (on_cut_[v] == 0) {
        continue;  // most of them: asked first, before two origins are looked up
      }
      const VertexOrigin& own = mesh_.vertex_origin(v);
      const VertexId point = own.kind == VertexOrigin::Kind::kDuplicate ? own.parents[0] : v;
      const VertexOrigin& origin = mesh_.vertex_origin(point);
      if (origin.kind == VertexOrigin::Kind::kCombination && origin.parent_count == 3) {
        points.emplace_back(v, point);
      }
    }
  }
  std::sort(points.begin(), points.end());
  points.erase(std::unique(points.begin(), points.end()), points.end());
  std::vector<VertexId> sliding_vertices;  // sorted: hundreds of points against hundreds
  sliding_vertices.reserve(provisional_.size());
  for (const Provisional& blade_point : provisional_) {
    sliding_vertices.push_back(blade_point.vertex);
  }
  std::sort(sliding_vertices.begin(), sliding_vertices.end());
  bool collapsed = false;
  for (const auto& [vertex, point] : points) {
    if (mesh_.vertex_tets(vertex).empty() || !opened_at(mesh_, marks_, vertex)) {
      continue;
    }
    const bool sliding =
        std::binary_search(sliding_vertices.begin(), sliding_vertices.end(), vertex);
    const VertexOrigin& origin = mesh_.vertex_origin(point);
    const std::array<VertexId, 4> corners{origin.parents[0], origin.parents[1], origin.parents[2],
                                          kInvalidId};
    // Still sliding with the blade, or the blade still crosses its face: the wound's front may
    // lie at the vertex. Once the blade has left the face, the cut crosses it completely and
    // the vertex is one more point inside it, on both sides.
    if (sliding || segment_intersects_triangle(pose_.tip, pose_.base, position(corners[0]),
                                               position(corners[1]), position(corners[2]))) {
      continue;
    }
    if (!flat_boundary_fan(mesh_, vertex)) {
      continue;  // no collapse keeps a bent piece of boundary as it is (boundary_kept_flat)
    }
    // Targets: vertices of the cut on the face's boundary next to it, nearest first; the
    // collapse keeps the boundary there flat (boundary_kept_flat), so each side's copy of the
    // wound is retriangulated alike.
    std::vector<std::pair<double, VertexId>> targets;
    for (TetId t : mesh_.vertex_tets(vertex)) {
      for (VertexId u : mesh_.tet(t)) {
        if (u != vertex && on_cut_[u] != 0 && on_feature_boundary(mesh_, u, corners, 3)) {
          targets.emplace_back((mesh_.rest_position(u) - mesh_.rest_position(vertex)).norm(), u);
        }
      }
    }
    std::sort(targets.begin(), targets.end());
    targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
    for (const auto& candidate : targets) {
      if (try_collapse(vertex, candidate.second)) {
        collapsed = true;
        break;
      }
    }
  }
  return collapsed;
}

void SubdivisionCutter::collapse_left_behind() {
  for (const Provisional& left : left_behind_) {
    const VertexId vertex = left.vertex;
    // Still a feature corner of a blade-line vertex that slides on: it stays.
    bool needed = false;
    for (const Provisional& point : next_provisional_) {
      needed = needed || std::find(point.corners.begin(), point.corners.begin() + point.count,
                                   vertex) != point.corners.begin() + point.count;
    }
    if (needed || mesh_.vertex_tets(vertex).empty()) {
      continue;
    }
    // Targets: crossings this move split, next to it, on its feature's boundary; nearest first.
    std::vector<std::pair<double, VertexId>> targets;
    for (VertexId u : crossings_made_) {
      if (mesh_.find_edge(vertex, u) != kInvalidId &&
          on_feature_boundary(mesh_, u, left.corners, left.count)) {
        targets.emplace_back((mesh_.rest_position(u) - mesh_.rest_position(vertex)).norm(), u);
      }
    }
    std::sort(targets.begin(), targets.end());
    for (const auto& candidate : targets) {
      if (try_collapse(vertex, candidate.second)) {
        break;
      }
    }
  }
  left_behind_.clear();
  crossings_made_.clear();
}

}  // namespace incise
