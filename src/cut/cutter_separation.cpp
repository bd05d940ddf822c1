// Opening the cut: which faces lie on the swept surface and part the tetrahedra on their two
// sides, duplicating vertices where cut faces separate them, resolving pinched edges, and
// giving slivers back to one side.

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/separation.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "triangle_index.hpp"

namespace incise {

using namespace cutter_detail;  // NOLINT(google-build-using-namespace): the cutter's own helpers

namespace {

/// The most sweeps (moves in which the blade moved) one face is checked across for one sheet.
constexpr std::int64_t kMostSweepsAcrossAFace = 4096;

}  // namespace

std::size_t SubdivisionCutter::separate(VertexId vertex) {
  const std::vector<VertexId> copies = separate_at_cut_faces(
      mesh_, vertex, [this](TetId tet, int face) { return marks_.is_cut(tet, face); });
  separated_.insert(separated_.end(), copies.size(), vertex);
  return copies.size();
}

void SubdivisionCutter::around_parted(VertexId vertex, VertexId first_copy,
                                      std::vector<VertexId>& around) const {
  around.clear();
  const auto add = [&](VertexId v) {
    for (TetId t : mesh_.vertex_tets(v)) {
      const Tet& corners = mesh_.tet(t);
      around.insert(around.end(), corners.begin(), corners.end());
    }
  };
  add(vertex);
  for (auto copy = first_copy; static_cast<std::size_t>(copy) < mesh_.vertex_count(); ++copy) {
    add(copy);
  }
}

void SubdivisionCutter::resolve_pinched_edges(std::vector<VertexId> vertices) {
  // Where the cut surface covers an edge whose two ends both lie on the crack front, neither end
  // can be separated and two wedges stay pinched along the edge (four boundary faces meet
  // there). Splitting the edge puts a vertex inside the cut, which can be separated.
  // Every round rescans the whole neighbourhood touched so far: separating one vertex can pinch
  // an edge between two others.
  for (int round = 0; round < 64; ++round) {
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    // Groups around a vertex that now touch only along edges come apart first.
    const auto first_copy = static_cast<VertexId>(mesh_.vertex_count());
    for (std::size_t i = 0, n = vertices.size(); i < n; ++i) {
      const auto copies_from = static_cast<VertexId>(mesh_.vertex_count());
      const std::size_t copies = separate(vertices[i]);
      stats_.vertices_duplicated += copies;
      if (copies == 0) {
        continue;
      }
      // Parting a vertex can pinch an edge between two of its neighbours on the cut (found by
      // the soak: tests/data/soak_findings/fixed/seed-30212, seed-31001): they are checked too.
      around_parted(vertices[i], copies_from, scratch_vertices_);
      for (VertexId u : scratch_vertices_) {
        if (on_cut_[u] != 0) {
          vertices.push_back(u);
        }
      }
    }
    for (auto v = first_copy; static_cast<std::size_t>(v) < mesh_.vertex_count(); ++v) {
      vertices.push_back(v);
    }
    const std::vector<std::pair<VertexId, VertexId>> pinched =
        pinched_edges(mesh_, vertices, [this](VertexId v) { return on_cut_[v] != 0; });
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
  std::int64_t nearest = swept_->nearest(centroid(p), allowed * (1.0 + 1e-9) + round_off, nullptr);
  if (nearest < 0) {
    // A blade that turns as it moves (any hand, the mouse) sweeps a curved surface, flat only
    // move by move: a face with its corners on it bulges off it in between by a small fraction
    // of its size. That is allowed where the corners lie on one continuous sheet, swept by
    // consecutive sweeps that all pass near the face; a face bridging two sheets (a path that
    // comes back near itself) is not taken.
    const double bulge = sheet_bulge(p, corners);
    if (bulge <= 0.0) {
      return false;
    }
    double off = 0.0;
    nearest = swept_->nearest(centroid(p), bulge, &off);
    if (nearest < 0) {
      return false;
    }
    // Both tetrahedra farther off the sheet than the face bulges, each on its side: a flat one
    // lying along the sheet stays whole on one side rather than being cut out of both.
    const auto& plane = swept_->triangle(static_cast<std::size_t>(nearest));
    const Vec3 normal = (plane[1] - plane[0]).cross(plane[2] - plane[0]).normalized();
    const double here = normal.dot(centroid(rest_corners(mesh_, tet)) - plane[0]);
    const double there = normal.dot(centroid(rest_corners(mesh_, neighbor)) - plane[0]);
    return std::min(std::abs(here), std::abs(there)) > 2.0 * off && (here > 0.0) != (there > 0.0);
  }
  // Sides: each tetrahedron is on the side of its centroid (one side per tetrahedron, so a flat
  // one whose corners all lie on the cut joins one side and is not cut out of both; a thin
  // region that still falls between cut faces is given back to one side by keep_no_shards).
  const auto& plane = swept_->triangle(static_cast<std::size_t>(nearest));
  return side_of(centroid(rest_corners(mesh_, tet)), plane) !=
         side_of(centroid(rest_corners(mesh_, neighbor)), plane);
}

double SubdivisionCutter::sheet_bulge(const std::array<Vec3, 3>& face,
                                      const std::array<VertexId, 3>& corners) const {
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  const double size = longest_edge(face);
  const double round_off = 1e-9 * size;
  for (std::size_t k = 0; k < 3; ++k) {
    const std::int64_t nearest =
        swept_->nearest(face[k], cut_offset_[corners[k]] * (1.0 + 1e-9) + round_off, nullptr);
    if (nearest < 0) {
      return 0.0;
    }
    const std::int64_t sweep = swept_->tag(static_cast<std::size_t>(nearest));
    first = std::min(first, sweep);
    last = std::max(last, sweep);
  }
  if (last - first > kMostSweepsAcrossAFace) {
    return 0.0;
  }
  // Every sweep from the first corner's to the last one's passes within the face's size.
  const std::vector<std::int64_t> near = swept_->tags_within(centroid(face), size, first, last);
  if (static_cast<std::int64_t>(near.size()) != last - first + 1) {
    return 0.0;
  }
  return kSweptSurfaceBulge * size;
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
  StampedSet& large = shard_walks_.large;
  StampedSet& checked = shard_walks_.checked;
  StampedSet& inside = shard_walks_.inside;
  large.clear(mesh_.tet_count());
  checked.clear(mesh_.tet_count());
  std::vector<TetId> region;
  for (const auto& [tet, face] : marked_) {
    const TetId across = mesh_.tet_neighbors(tet)[face];
    for (TetId start : {tet, across}) {
      if (start < 0 || large.contains(start) || checked.contains(start)) {
        continue;
      }
      region.assign(1, start);
      inside.clear(mesh_.tet_count());
      inside.insert(start);
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
        for (TetId r : region) {
          large.insert(r);
        }
        continue;
      }
      for (TetId r : region) {
        checked.insert(r);
      }
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
            const std::array<Vec3, 3> corners = rest_face(mesh_, r, g);
            if (swept_side(other, centroid(corners), face_reach(r, g)) == join) {
              marks_.unmark(r, g);
              stats_.cut_area -= area(corners);
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
  // As far as a face on a curved sheet may bulge off it (sheet_bulge), so its side is found.
  const double size = longest_edge(rest_face(mesh_, tet, local_face));
  return std::max(offset * (1.0 + 1e-9) + 1e-9 * size, kSweptSurfaceBulge * size);
}

int SubdivisionCutter::swept_side(TetId tet, const Vec3& near_point, double radius) const {
  const std::array<Vec3, 4> corners = rest_corners(mesh_, tet);
  const std::int64_t nearest = swept_->nearest(near_point, radius, nullptr);
  if (nearest < 0) {
    return 0;
  }
  return side_of(centroid(corners), swept_->triangle(static_cast<std::size_t>(nearest)));
}

}  // namespace incise
