#include "incise/planning/osteotomy.hpp"

#include <CGAL/box_intersection_d.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "incise/core/error.hpp"
#include "incise/mesh/disjoint_sets.hpp"
#include "incise/mesh/predicates.hpp"
#include "nearest_triangle.hpp"

namespace incise::planning {

namespace {

Vec3 centroid(const SurfaceMesh& mesh, const Triangle& t) {
  return (mesh.points[static_cast<std::size_t>(t[0])] +
          mesh.points[static_cast<std::size_t>(t[1])] +
          mesh.points[static_cast<std::size_t>(t[2])]) /
         3.0;
}

/// m: how far a moved segment may reach beyond the plane that cut it (rounding).
constexpr double kDepthTolerance = 1e-6;

/// Whether the plane's disc separates the two points.
bool separates(const CutPlane& plane, const Vec3& p, const Vec3& q) {
  const double sp = (p - plane.point).dot(plane.normal);
  const double sq = (q - plane.point).dot(plane.normal);
  if ((sp >= 0.0) == (sq >= 0.0)) {
    return false;
  }
  auto in_disc = [&](const Vec3& x, double s) {
    return ((x - plane.point) - s * plane.normal).norm() <= plane.radius;
  };
  return in_disc(p, sp) && in_disc(q, sq);
}

}  // namespace

BoneSegments segment_bone(const SurfaceMesh& bone, std::span<const CutPlane> input_planes) {
  std::vector<CutPlane> planes(input_planes.begin(), input_planes.end());
  for (CutPlane& plane : planes) {
    if (!(plane.normal.norm() > 0.0) || !plane.normal.allFinite() || !plane.point.allFinite()) {
      throw InputError("an osteotomy plane needs a finite point and a nonzero normal");
    }
    plane.normal.normalize();
  }
  const std::size_t count = bone.triangles.size();
  std::vector<Vec3> centroids(count);
  for (std::size_t t = 0; t < count; ++t) {
    centroids[t] = centroid(bone, bone.triangles[t]);
  }
  std::map<std::pair<VertexId, VertexId>, std::vector<int>> edge_triangles;
  for (std::size_t t = 0; t < count; ++t) {
    const Triangle& tri = bone.triangles[t];
    for (int e = 0; e < 3; ++e) {
      edge_triangles[std::minmax(tri[static_cast<std::size_t>(e)],
                                 tri[static_cast<std::size_t>((e + 1) % 3)])]
          .push_back(static_cast<int>(t));
    }
  }
  DisjointSets sets(count);
  for (const auto& [edge, triangles] : edge_triangles) {
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      for (std::size_t j = i + 1; j < triangles.size(); ++j) {
        const Vec3& p = centroids[static_cast<std::size_t>(triangles[i])];
        const Vec3& q = centroids[static_cast<std::size_t>(triangles[j])];
        const bool cut = std::any_of(planes.begin(), planes.end(),
                                     [&](const CutPlane& plane) { return separates(plane, p, q); });
        if (!cut) {
          sets.join(triangles[i], triangles[j]);
        }
      }
    }
  }
  BoneSegments segments;
  segments.triangle_segment.assign(count, -1);
  std::map<VertexId, int> segment_of_root;
  for (std::size_t t = 0; t < count; ++t) {
    const VertexId root = sets.find(static_cast<VertexId>(t));
    const auto [it, added] = segment_of_root.emplace(root, segments.count);
    if (added) {
      ++segments.count;
      segments.sizes.push_back(0);
    }
    segments.triangle_segment[t] = it->second;
    ++segments.sizes[static_cast<std::size_t>(it->second)];
  }
  return segments;
}

Vec3 RigidMove::apply(const Vec3& x) const {
  const Eigen::AngleAxisd rotation(angle, axis.normalized());
  return rotation * (x - center) + center + translation;
}

int nearest_segment(const SurfaceMesh& bone, const BoneSegments& segments, const Vec3& point) {
  const NearestTriangle nearest(bone.points, bone.triangles);
  return segments.triangle_segment[static_cast<std::size_t>(nearest.closest(point).triangle)];
}

std::vector<std::array<Vec3, 3>> moved_triangles(const SurfaceMesh& bone,
                                                 const BoneSegments& segments,
                                                 std::span<const RigidMove> segment_moves) {
  std::vector<std::array<Vec3, 3>> moved(bone.triangles.size());
  for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
    const RigidMove& move = segment_moves[static_cast<std::size_t>(segments.triangle_segment[t])];
    for (int c = 0; c < 3; ++c) {
      moved[t][static_cast<std::size_t>(c)] = move.apply(
          bone.points[static_cast<std::size_t>(bone.triangles[t][static_cast<std::size_t>(c)])]);
    }
  }
  return moved;
}

std::vector<Interpenetration> find_interpenetrations(const SurfaceMesh& bone,
                                                     const BoneSegments& segments,
                                                     std::span<const RigidMove> segment_moves,
                                                     std::span<const CutPlane> planes) {
  const std::vector<std::array<Vec3, 3>> moved = moved_triangles(bone, segments, segment_moves);
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
  std::vector<Box> boxes;
  boxes.reserve(moved.size());
  for (std::size_t t = 0; t < moved.size(); ++t) {
    double low[3];
    double high[3];
    for (int k = 0; k < 3; ++k) {
      low[k] = std::min({moved[t][0][k], moved[t][1][k], moved[t][2][k]});
      high[k] = std::max({moved[t][0][k], moved[t][1][k], moved[t][2][k]});
    }
    boxes.emplace_back(low, high, static_cast<int>(t));
  }
  std::map<std::pair<int, int>, int> crossings;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& a, const Box& b) {
    const auto ta = static_cast<std::size_t>(a.info());
    const auto tb = static_cast<std::size_t>(b.info());
    const int sa = segments.triangle_segment[ta];
    const int sb = segments.triangle_segment[tb];
    if (sa == sb) {
      return;
    }
    auto moves = [&](int segment) {
      const RigidMove& m = segment_moves[static_cast<std::size_t>(segment)];
      return m.angle != 0.0 || m.translation != Vec3::Zero();
    };
    if (!moves(sa) && !moves(sb)) {
      return;
    }
    for (VertexId u : bone.triangles[ta]) {
      for (VertexId v : bone.triangles[tb]) {
        if (u == v) {
          return;  // neighbours along the cut
        }
      }
    }
    auto corner = [&](std::size_t t, int c) -> const Vec3& {
      return bone.points[static_cast<std::size_t>(bone.triangles[t][static_cast<std::size_t>(c)])];
    };
    // Crossings the bone had before any move (scanned surfaces self-intersect here and there)
    // are not the move's doing.
    if (triangles_intersect(moved[ta][0], moved[ta][1], moved[ta][2], moved[tb][0], moved[tb][1],
                            moved[tb][2]) &&
        !triangles_intersect(corner(ta, 0), corner(ta, 1), corner(ta, 2), corner(tb, 0),
                             corner(tb, 1), corner(tb, 2))) {
      ++crossings[std::minmax(sa, sb)];
    }
  });
  // Segments that share an edge were cut apart by a plane; one moved into the other's side of
  // it overlaps it even where no surfaces cross (a cap pushed into a closed bone).
  std::set<std::pair<int, int>> neighbours;
  {
    std::map<std::pair<VertexId, VertexId>, int> first_segment;
    for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
      for (int e = 0; e < 3; ++e) {
        const auto key = std::minmax(bone.triangles[t][static_cast<std::size_t>(e)],
                                     bone.triangles[t][static_cast<std::size_t>((e + 1) % 3)]);
        const int s = segments.triangle_segment[t];
        const auto [it, added] = first_segment.emplace(key, s);
        if (!added && it->second != s) {
          neighbours.insert(std::minmax(it->second, s));
        }
      }
    }
  }
  auto moved_segment = [&](int segment) {
    const RigidMove& m = segment_moves[static_cast<std::size_t>(segment)];
    return m.angle != 0.0 || m.translation != Vec3::Zero();
  };
  std::set<std::pair<int, int>> candidates = neighbours;
  for (const auto& [pair, count] : crossings) {
    candidates.insert(pair);
  }
  std::vector<Interpenetration> found;
  for (const auto& pair : candidates) {
    if (!moved_segment(pair.first) && !moved_segment(pair.second)) {
      continue;
    }
    Interpenetration item;
    item.first = pair.first;
    item.second = pair.second;
    const auto crossing = crossings.find(pair);
    item.crossing_triangle_pairs = crossing == crossings.end() ? 0 : crossing->second;
    for (const CutPlane& raw : planes) {
      CutPlane plane = raw;
      plane.normal.normalize();
      double side[2] = {0.0, 0.0};
      int counted[2] = {0, 0};
      for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
        const int s = segments.triangle_segment[t];
        const int which = s == pair.first ? 0 : (s == pair.second ? 1 : -1);
        if (which >= 0) {
          side[which] += (centroid(bone, bone.triangles[t]) - plane.point).dot(plane.normal);
          ++counted[which];
        }
      }
      if (counted[0] == 0 || counted[1] == 0 || (side[0] >= 0.0) == (side[1] >= 0.0)) {
        continue;
      }
      // Triangles on the cut straddle it by up to an edge before any move: the depth is what
      // the move added beyond that.
      for (int which = 0; which < 2; ++which) {
        const int segment = which == 0 ? pair.first : pair.second;
        if (!moved_segment(segment)) {
          continue;
        }
        const double sign = side[which] >= 0.0 ? 1.0 : -1.0;
        double before = 0.0;
        double after = 0.0;
        for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
          if (segments.triangle_segment[t] != segment) {
            continue;
          }
          for (int c = 0; c < 3; ++c) {
            const Vec3& original = bone.points[static_cast<std::size_t>(
                bone.triangles[t][static_cast<std::size_t>(c)])];
            const Vec3 offset = original - plane.point;
            const double along = offset.dot(plane.normal);
            if ((offset - along * plane.normal).norm() <= plane.radius) {
              before = std::max(before, -sign * along);
              after = std::max(
                  after,
                  -sign * (moved[t][static_cast<std::size_t>(c)] - plane.point).dot(plane.normal));
            }
          }
        }
        item.depth = std::max(item.depth, after - before);
      }
    }
    if (item.crossing_triangle_pairs > 0 || item.depth > kDepthTolerance) {
      found.push_back(item);
    }
  }
  return found;
}

}  // namespace incise::planning
