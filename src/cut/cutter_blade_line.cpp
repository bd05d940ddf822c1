// Vertices on the blade line: inserted where it crosses faces and at its tip, left out where
// they would thin a tetrahedron, and slid along with the blade at the next pose.

#include <algorithm>
#include <cmath>
#include <limits>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
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
    double star_before = 0.0;  // m^3, rest
    double star_after = 0.0;
    for (TetId t : mesh_.vertex_tets(vertex)) {
      const Tet& v = mesh_.tet(t);
      const int local = mesh_.local_index(t, vertex);
      const std::array<Vec3, 4> before = rest_corners(mesh_, t);
      std::array<Vec3, 4> after = before;
      after[local] = rest;
      star_before += signed_volume(before[0], before[1], before[2], before[3]);
      star_after += signed_volume(after[0], after[1], after[2], after[3]);
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
}

}  // namespace incise
