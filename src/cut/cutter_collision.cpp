// Collision detection: the tetrahedra a swept surface touches, the edges it crosses, the
// swept surface recorded at rest, the seed's cut-edge codes and cases, vertices put on the cut.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>

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

SubdivisionCutter::Contact SubdivisionCutter::detect(
    const std::vector<std::array<Vec3, 3>>& triangles) {
  Contact contact;
  // Candidates: the tetrahedra in the grid cells of each swept triangle whose boxes meet its
  // box (the exact test is the expensive part of collision detection), then tested exactly.
  struct Candidate {
    TetId tet;
    std::uint32_t triangle;
  };
  std::vector<Candidate> candidates;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    Vec3 low;
    Vec3 high;
    triangle_bounds(triangles[i], low, high);
    grid_.query(low, high, scratch_);
    for (TetId t : scratch_) {
      const Tet& v = mesh_.tet(t);
      Vec3 tet_low = position(v[0]);
      Vec3 tet_high = tet_low;
      for (int k = 1; k < 4; ++k) {
        tet_low = tet_low.cwiseMin(position(v[k]));
        tet_high = tet_high.cwiseMax(position(v[k]));
      }
      if ((tet_low.array() > high.array()).any() || (tet_high.array() < low.array()).any()) {
        continue;
      }
      candidates.push_back({t, static_cast<std::uint32_t>(i)});
    }
  }
  std::vector<std::uint8_t> touches;
  test_each<Candidate>(candidates, touches, [&](const Candidate& candidate) -> std::uint8_t {
    const Tet& v = mesh_.tet(candidate.tet);
    const auto& triangle = triangles[candidate.triangle];
    return triangle_intersects_tet(triangle[0], triangle[1], triangle[2], position(v[0]),
                                   position(v[1]), position(v[2]), position(v[3]))
               ? 1
               : 0;
  });
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (touches[i] != 0) {
      contact.touched.push_back(candidates[i].tet);
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
  // What the first swept triangle an edge meets does to it: nothing, a crossing at t, or its
  // ends snapped onto the cut.
  struct Meeting {
    double t = 0.0;
    std::uint8_t crossed = 0;
    std::uint8_t snap_a = 0;
    std::uint8_t snap_b = 0;
  };
  std::vector<Meeting> meetings;
  test_each<std::pair<VertexId, VertexId>>(
      edges, meetings, [&](const std::pair<VertexId, VertexId>& edge) {
        const Vec3& pa = position(edge.first);
        const Vec3& pb = position(edge.second);
        Meeting meeting;
        for (const auto& triangle : triangles) {
          if (!segment_intersects_triangle(pa, pb, triangle[0], triangle[1], triangle[2])) {
            continue;
          }
          const Vec3 normal = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]);
          const double da = normal.dot(pa - triangle[0]);
          const double db = normal.dot(pb - triangle[0]);
          if (da == db) {
            // The edge lies in the blade's plane: its ends on the swept triangle are on the cut.
            const auto on_triangle = [&](const Vec3& end) -> std::uint8_t {
              return squared_distance_to_triangle(end, triangle[0], triangle[1], triangle[2]) <=
                             1e-24 * normal.norm()
                         ? 1
                         : 0;
            };
            meeting.snap_a = on_triangle(pa);
            meeting.snap_b = on_triangle(pb);
            break;
          }
          const double t = std::clamp(da / (da - db), 0.0, 1.0);
          if (t <= options_.snap_fraction) {
            meeting.snap_a = 1;
          } else if (t >= 1.0 - options_.snap_fraction) {
            meeting.snap_b = 1;
          } else {
            meeting.crossed = 1;
            meeting.t = t;
          }
          break;
        }
        return meeting;
      });
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const Meeting& meeting = meetings[i];
    const auto [a, b] = edges[i];
    if (meeting.snap_a != 0) {
      contact.snapped.push_back(a);
    }
    if (meeting.snap_b != 0) {
      contact.snapped.push_back(b);
    }
    if (meeting.crossed != 0) {
      contact.crossings.push_back({a, b, meeting.t});
    }
  }
  return contact;
}

void SubdivisionCutter::record_swept(const std::vector<std::array<Vec3, 3>>& triangles,
                                     const Contact& contact) {
  move_rest_triangles_.clear();
  // Triangles are tagged with the sweep that made them: consecutive tags are consecutive
  // pieces of one sheet (a move in which the blade stood still adds nothing and no tag).
  const std::size_t before = swept_->size();
  const auto tag = static_cast<std::int64_t>(stats_.sweeps);
  move_sweep_ = -1;
  if (positions_ == nullptr) {
    for (const auto& triangle : triangles) {
      swept_->add(triangle, Vec3::Constant(-std::numeric_limits<double>::max()),
                  Vec3::Constant(std::numeric_limits<double>::max()), tag);
      move_rest_triangles_.push_back(triangle);
    }
    if (swept_->size() > before) {
      move_sweep_ = tag;
      ++stats_.sweeps;
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
      swept_->add(image, low - margin, high + margin, tag);
      move_rest_triangles_.push_back(image);
    }
  }
  if (swept_->size() > before) {
    move_sweep_ = tag;
    ++stats_.sweeps;
  }
}

void SubdivisionCutter::classify(const Contact& contact, const BladePose& pose) {
  std::vector<std::pair<VertexId, VertexId>> crossed;
  for (const Crossing& crossing : contact.crossings) {
    crossed.emplace_back(std::min(crossing.a, crossing.b), std::max(crossing.a, crossing.b));
  }
  std::sort(crossed.begin(), crossed.end());
  // The seed's per-move code and case of every tetrahedron this move crossed.
  std::vector<std::pair<TetId, std::uint8_t>> coded;
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
    if (code != 0) {
      coded.emplace_back(t, code);
    }
  }
  std::vector<std::uint8_t> partial;
  test_each<std::pair<TetId, std::uint8_t>>(
      coded, partial, [&](const std::pair<TetId, std::uint8_t>& tet) -> std::uint8_t {
        const Tet& v = mesh_.tet(tet.first);
        return segment_intersects_tet(pose.tip, pose.base, position(v[0]), position(v[1]),
                                      position(v[2]), position(v[3]))
                   ? 1
                   : 0;
      });
  for (std::size_t i = 0; i < coded.size(); ++i) {
    ++stats_.case_counts[static_cast<std::size_t>(
        cut_case_table()[cut_state_key(coded[i].second, partial[i] != 0)].kind)];
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

}  // namespace incise
