#include "incise/planning/osteotomy.hpp"

#include <CGAL/box_intersection_d.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
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

namespace {

/// Pairs of triangles sharing an edge, by the edge.
std::map<std::pair<VertexId, VertexId>, std::vector<int>> triangles_by_edge(
    const SurfaceMesh& bone) {
  std::map<std::pair<VertexId, VertexId>, std::vector<int>> edge_triangles;
  for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
    const Triangle& tri = bone.triangles[t];
    for (std::size_t e = 0; e < 3; ++e) {
      edge_triangles[std::minmax(tri[e], tri[(e + 1) % 3])].push_back(static_cast<int>(t));
    }
  }
  return edge_triangles;
}

/// Fills count, sizes and volumes from triangle_segment (labels 0 .. count - 1), and returns
/// how many cut edges each pair of segments shares.
std::map<std::pair<int, int>, int> measure_segments(
    const SurfaceMesh& bone,
    const std::map<std::pair<VertexId, VertexId>, std::vector<int>>& edge_triangles,
    BoneSegments& segments) {
  segments.count = 0;
  for (int s : segments.triangle_segment) {
    segments.count = std::max(segments.count, s + 1);
  }
  const auto count = static_cast<std::size_t>(segments.count);
  segments.sizes.assign(count, 0);
  segments.volumes.assign(count, 0.0);
  std::map<std::pair<int, int>, int> shared;
  std::vector<Vec3> apex_sum(count, Vec3::Zero());
  std::vector<int> apex_count(count, 0);
  for (const auto& [edge, triangles] : edge_triangles) {
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      for (std::size_t j = i + 1; j < triangles.size(); ++j) {
        const int a = segments.triangle_segment[static_cast<std::size_t>(triangles[i])];
        const int b = segments.triangle_segment[static_cast<std::size_t>(triangles[j])];
        if (a == b) {
          continue;
        }
        ++shared[std::minmax(a, b)];
        const Vec3 middle = 0.5 * (bone.points[static_cast<std::size_t>(edge.first)] +
                                   bone.points[static_cast<std::size_t>(edge.second)]);
        for (int s : {a, b}) {
          apex_sum[static_cast<std::size_t>(s)] += middle;
          ++apex_count[static_cast<std::size_t>(s)];
        }
      }
    }
  }
  // A cone from the centre of a segment's cut edges closes its cut nearly flat: the volume is
  // that of the piece the saw leaves.
  std::vector<Vec3> apex(count, Vec3::Zero());
  for (std::size_t s = 0; s < count; ++s) {
    if (apex_count[s] > 0) {
      apex[s] = apex_sum[s] / apex_count[s];
    }
  }
  for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
    const auto s = static_cast<std::size_t>(segments.triangle_segment[t]);
    const Vec3 a = bone.points[static_cast<std::size_t>(bone.triangles[t][0])] - apex[s];
    const Vec3 b = bone.points[static_cast<std::size_t>(bone.triangles[t][1])] - apex[s];
    const Vec3 c = bone.points[static_cast<std::size_t>(bone.triangles[t][2])] - apex[s];
    ++segments.sizes[s];
    segments.volumes[s] += a.dot(b.cross(c)) / 6.0;
  }
  return shared;
}

}  // namespace

BoneSegments segment_bone(const SurfaceMesh& bone, std::span<const CutPlane> input_planes,
                          double least_volume) {
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
  const auto edge_triangles = triangles_by_edge(bone);
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
    const auto [it, added] =
        segment_of_root.emplace(root, static_cast<int>(segment_of_root.size()));
    segments.triangle_segment[t] = it->second;
  }
  auto shared = measure_segments(bone, edge_triangles, segments);
  // Fragments join a neighbour, smallest first, until every segment that has a neighbour
  // encloses the least volume.
  for (;;) {
    int smallest = -1;
    for (int s = 0; s < segments.count; ++s) {
      const bool has_neighbour = std::any_of(shared.begin(), shared.end(), [&](const auto& item) {
        return item.first.first == s || item.first.second == s;
      });
      if (has_neighbour && std::abs(segments.volumes[static_cast<std::size_t>(s)]) < least_volume &&
          (smallest < 0 || std::abs(segments.volumes[static_cast<std::size_t>(s)]) <
                               std::abs(segments.volumes[static_cast<std::size_t>(smallest)]))) {
        smallest = s;
      }
    }
    if (smallest < 0) {
      break;
    }
    int into = -1;
    int most = 0;
    for (const auto& [pair, edges] : shared) {
      if ((pair.first == smallest || pair.second == smallest) && edges > most) {
        into = pair.first == smallest ? pair.second : pair.first;
        most = edges;
      }
    }
    // Relabel: the fragment takes its neighbour's label and the last label fills its place.
    const int last = segments.count - 1;
    for (int& s : segments.triangle_segment) {
      s = s == smallest ? into : s;
      s = s == last ? smallest : s;
    }
    ++segments.merged_fragments;
    shared = measure_segments(bone, edge_triangles, segments);
  }
  for (int s = 0; s < segments.count; ++s) {
    if (std::abs(segments.volumes[static_cast<std::size_t>(s)]) < least_volume) {
      ++segments.small_isolated;
    }
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

namespace {

/// Where segment pq crosses the plane of triangle abc inside it (barycentric coordinates not
/// below -1e-9), if it does. Pure.
std::optional<Vec3> segment_meets_triangle(const Vec3& p, const Vec3& q, const Vec3& a,
                                           const Vec3& b, const Vec3& c) {
  const Vec3 normal = (b - a).cross(c - a);
  const double dp = normal.dot(p - a);
  const double dq = normal.dot(q - a);
  if ((dp > 0.0 && dq > 0.0) || (dp < 0.0 && dq < 0.0) || dp == dq) {
    return std::nullopt;
  }
  const Vec3 x = p + (dp / (dp - dq)) * (q - p);
  const double area2 = normal.squaredNorm();
  const double u = normal.dot((c - b).cross(x - b)) / area2;
  const double v = normal.dot((a - c).cross(x - c)) / area2;
  const double w = 1.0 - u - v;
  constexpr double kSlack = -1e-9;
  if (u < kSlack || v < kSlack || w < kSlack) {
    return std::nullopt;
  }
  return x;
}

}  // namespace

std::vector<Vec3> crossing_points(const std::array<Vec3, 3>& first,
                                  const std::array<Vec3, 3>& second) {
  std::vector<Vec3> points;
  for (int which = 0; which < 2; ++which) {
    const std::array<Vec3, 3>& edges = which == 0 ? first : second;
    const std::array<Vec3, 3>& face = which == 0 ? second : first;
    for (std::size_t e = 0; e < 3; ++e) {
      if (const auto x =
              segment_meets_triangle(edges[e], edges[(e + 1) % 3], face[0], face[1], face[2])) {
        points.push_back(*x);
      }
    }
  }
  return points;
}

SegmentCuts segment_cuts(const SurfaceMesh& bone, const BoneSegments& segments,
                         std::span<const CutPlane> input_planes, double tolerance) {
  SegmentCuts result;
  result.planes.assign(input_planes.begin(), input_planes.end());
  for (CutPlane& plane : result.planes) {
    plane.normal.normalize();
  }
  result.tolerance = tolerance;
  const std::vector<CutPlane>& planes = result.planes;
  // Segments that share an edge were cut apart by a plane. For each such pair and each plane
  // with the two on opposite sides: the band about the plane that holds the triangles along
  // their cut (they straddle it by up to an edge), widened by the tolerance.
  std::map<std::pair<int, int>, std::vector<int>> cut_triangles;
  for (const auto& [edge, triangles] : triangles_by_edge(bone)) {
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      for (std::size_t j = i + 1; j < triangles.size(); ++j) {
        const int a = segments.triangle_segment[static_cast<std::size_t>(triangles[i])];
        const int b = segments.triangle_segment[static_cast<std::size_t>(triangles[j])];
        if (a != b) {
          auto& list = cut_triangles[std::minmax(a, b)];
          list.push_back(triangles[i]);
          list.push_back(triangles[j]);
        }
      }
    }
  }
  for (const auto& [pair, triangles] : cut_triangles) {
    for (std::size_t p = 0; p < planes.size(); ++p) {
      const CutPlane& plane = planes[p];
      double side[2] = {0.0, 0.0};
      for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
        const int s = segments.triangle_segment[t];
        if (s == pair.first || s == pair.second) {
          side[s == pair.first ? 0 : 1] +=
              (centroid(bone, bone.triangles[t]) - plane.point).dot(plane.normal);
        }
      }
      if ((side[0] >= 0.0) == (side[1] >= 0.0)) {
        continue;
      }
      SegmentCuts::Cut cut;
      cut.plane = p;
      cut.side[0] = side[0];
      cut.side[1] = side[1];
      for (int t : triangles) {
        for (VertexId v : bone.triangles[static_cast<std::size_t>(t)]) {
          cut.half_width = std::max(
              cut.half_width,
              std::abs((bone.points[static_cast<std::size_t>(v)] - plane.point).dot(plane.normal)));
        }
      }
      cut.half_width += tolerance;
      // Triangles on the cut straddle it by up to an edge before any move: the depth a move
      // makes is measured beyond that.
      for (int which = 0; which < 2; ++which) {
        const int segment = which == 0 ? pair.first : pair.second;
        const double sign = cut.side[which] >= 0.0 ? 1.0 : -1.0;
        for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
          if (segments.triangle_segment[t] != segment) {
            continue;
          }
          for (const VertexId v : bone.triangles[t]) {
            const Vec3 offset = bone.points[static_cast<std::size_t>(v)] - plane.point;
            const double along = offset.dot(plane.normal);
            if ((offset - along * plane.normal).norm() <= plane.radius) {
              cut.before[which] = std::max(cut.before[which], -sign * along);
            }
          }
        }
      }
      result.cuts[pair].push_back(cut);
    }
  }
  return result;
}

std::vector<Interpenetration> find_interpenetrations(const SurfaceMesh& bone,
                                                     const BoneSegments& segments,
                                                     std::span<const RigidMove> segment_moves,
                                                     std::span<const CutPlane> planes,
                                                     double tolerance) {
  return find_interpenetrations(bone, segments, segment_moves,
                                segment_cuts(bone, segments, planes, tolerance));
}

std::vector<Interpenetration> find_interpenetrations(const SurfaceMesh& bone,
                                                     const BoneSegments& segments,
                                                     std::span<const RigidMove> segment_moves,
                                                     const SegmentCuts& segment_cut_bands) {
  const std::vector<CutPlane>& planes = segment_cut_bands.planes;
  const double tolerance = segment_cut_bands.tolerance;
  const auto& cuts = segment_cut_bands.cuts;
  using Cut = SegmentCuts::Cut;
  auto moved_segment = [&](int segment) {
    const RigidMove& m = segment_moves[static_cast<std::size_t>(segment)];
    return m.angle != 0.0 || m.translation != Vec3::Zero();
  };
  const std::vector<std::array<Vec3, 3>> moved = moved_triangles(bone, segments, segment_moves);

  // Whether two moved triangles lie within the band of a cut their segments share.
  auto on_their_cut = [&](std::size_t ta, std::size_t tb, const std::pair<int, int>& pair) {
    const auto found = cuts.find(pair);
    if (found == cuts.end()) {
      return false;
    }
    for (const Cut& cut : found->second) {
      const CutPlane& plane = planes[cut.plane];
      auto within = [&](const std::array<Vec3, 3>& corners) {
        return std::all_of(corners.begin(), corners.end(), [&](const Vec3& x) {
          return std::abs((x - plane.point).dot(plane.normal)) <= cut.half_width;
        });
      };
      if (within(moved[ta]) && within(moved[tb])) {
        return true;
      }
      // Or where they cross lies within it: a triangle beside the cut that dips into the band
      // meets the other segment's cut face there (on the phantom head's DICOM series, 22 such
      // pairs refused the maxilla's 5 mm slide along its Le Fort cut).
      const std::vector<Vec3> where = crossing_points(moved[ta], moved[tb]);
      if (!where.empty() && std::all_of(where.begin(), where.end(), [&](const Vec3& x) {
            return std::abs((x - plane.point).dot(plane.normal)) <= cut.half_width;
          })) {
        return true;
      }
    }
    return false;
  };

  // Triangles of moved segments against all others (a still segment cannot cross another
  // still one: the moves are the news): boxes of the moved ones against themselves and against
  // the still ones.
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
  std::vector<Box> moving_boxes;
  std::vector<Box> still_boxes;
  for (std::size_t t = 0; t < moved.size(); ++t) {
    double low[3];
    double high[3];
    for (int k = 0; k < 3; ++k) {
      low[k] = std::min({moved[t][0][k], moved[t][1][k], moved[t][2][k]});
      high[k] = std::max({moved[t][0][k], moved[t][1][k], moved[t][2][k]});
    }
    (moved_segment(segments.triangle_segment[t]) ? moving_boxes : still_boxes)
        .emplace_back(low, high, static_cast<int>(t));
  }
  std::map<std::pair<int, int>, int> crossings;
  const auto check = [&](const Box& a, const Box& b) {
    const auto ta = static_cast<std::size_t>(a.info());
    const auto tb = static_cast<std::size_t>(b.info());
    const int sa = segments.triangle_segment[ta];
    const int sb = segments.triangle_segment[tb];
    if (sa == sb) {
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
    const auto pair = std::minmax(sa, sb);
    // Crossings the bone had before any move (scanned surfaces self-intersect here and there)
    // are not the move's doing; crossings on the cut the two share are contact.
    if (triangles_intersect(moved[ta][0], moved[ta][1], moved[ta][2], moved[tb][0], moved[tb][1],
                            moved[tb][2]) &&
        !triangles_intersect(corner(ta, 0), corner(ta, 1), corner(ta, 2), corner(tb, 0),
                             corner(tb, 1), corner(tb, 2)) &&
        !on_their_cut(ta, tb, pair)) {
      ++crossings[pair];
    }
  };
  CGAL::box_self_intersection_d(moving_boxes.begin(), moving_boxes.end(), check);
  CGAL::box_intersection_d(moving_boxes.begin(), moving_boxes.end(), still_boxes.begin(),
                           still_boxes.end(), check);

  std::set<std::pair<int, int>> candidates;
  for (const auto& [pair, list] : cuts) {
    candidates.insert(pair);
  }
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
    const auto pair_cuts = cuts.find(pair);
    for (const Cut& cut : pair_cuts == cuts.end() ? std::vector<Cut>{} : pair_cuts->second) {
      const CutPlane& plane = planes[cut.plane];
      // Triangles on the cut straddle it by up to an edge before any move: the depth is what
      // the move added beyond that.
      for (int which = 0; which < 2; ++which) {
        const int segment = which == 0 ? pair.first : pair.second;
        if (!moved_segment(segment)) {
          continue;
        }
        const double sign = cut.side[which] >= 0.0 ? 1.0 : -1.0;
        const double before = cut.before[which];
        double after = 0.0;
        for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
          if (segments.triangle_segment[t] != segment) {
            continue;
          }
          for (int c = 0; c < 3; ++c) {
            const Vec3 offset = bone.points[static_cast<std::size_t>(
                                    bone.triangles[t][static_cast<std::size_t>(c)])] -
                                plane.point;
            const double along = offset.dot(plane.normal);
            if ((offset - along * plane.normal).norm() <= plane.radius) {
              after = std::max(
                  after,
                  -sign * (moved[t][static_cast<std::size_t>(c)] - plane.point).dot(plane.normal));
            }
          }
        }
        item.depth = std::max(item.depth, after - before);
      }
    }
    if (item.crossing_triangle_pairs > 0 || item.depth > tolerance) {
      found.push_back(item);
    }
  }
  return found;
}

}  // namespace incise::planning
