// The seed's generic split of every cut tetrahedron (all edges and faces), for comparison.

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "triangle_index.hpp"

namespace incise {

using namespace cutter_detail;  // NOLINT(google-build-using-namespace): the cutter's own helpers

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

}  // namespace incise
