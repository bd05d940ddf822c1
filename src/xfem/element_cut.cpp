#include "incise/xfem/element_cut.hpp"

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {
namespace {

/// Local edge index of corners i and j (either order).
int edge_of(int i, int j) {
  for (int k = 0; k < 6; ++k) {
    const auto& edge = tet_local::kEdges[static_cast<std::size_t>(k)];
    if ((edge[0] == i && edge[1] == j) || (edge[0] == j && edge[1] == i)) {
      return k;
    }
  }
  INCISE_ASSERT(false, "corners of a tetrahedron share an edge");
}

/// Six times the signed volume of (origin, p, q, r).
double triple(const Vec3& origin, const Vec3& p, const Vec3& q, const Vec3& r) {
  return (p - origin).dot((q - origin).cross(r - origin));
}

/// Six times the volume a closed surface's piece (a planar polygon fan) contributes.
double fan_volume(const Vec3& origin, const std::vector<Vec3>& polygon) {
  double sum = 0.0;
  for (std::size_t m = 1; m + 1 < polygon.size(); ++m) {
    sum += triple(origin, polygon[0], polygon[m], polygon[m + 1]);
  }
  return sum;
}

}  // namespace

Vec3 crossing_point(const std::array<Vec3, 4>& corners, const ElementCut& cut, int i, int j) {
  const int k = edge_of(i, j);
  const auto& edge = tet_local::kEdges[static_cast<std::size_t>(k)];
  const double t = cut.crossing[static_cast<std::size_t>(k)];
  INCISE_ASSERT(t > 0.0 && t < 1.0, "a crossing lies inside its edge");
  return (1.0 - t) * corners[static_cast<std::size_t>(edge[0])] +
         t * corners[static_cast<std::size_t>(edge[1])];
}

bool ElementCut::splits() const {
  const auto on_far = std::count(on_b.begin(), on_b.end(), true);
  return on_far > 0 && on_far < 4;
}

std::vector<int> cut_polygon_edges(const std::array<Vec3, 4>& corners, const ElementCut& cut) {
  if (!cut.splits()) {
    return {};
  }
  std::vector<int> side_a;
  std::vector<int> side_b;
  for (int k = 0; k < 4; ++k) {
    (cut.on_b[static_cast<std::size_t>(k)] ? side_b : side_a).push_back(k);
  }
  std::vector<int> edges;
  if (side_a.size() == 1 || side_b.size() == 1) {
    const bool lone_a = side_a.size() == 1;
    const int lone = lone_a ? side_a[0] : side_b[0];
    for (int other : lone_a ? side_b : side_a) {
      edges.push_back(edge_of(lone, other));
    }
  } else {
    // Two and two: the crossed edges a0-b0, a0-b1, a1-b1, a1-b0 form a cycle.
    edges = {edge_of(side_a[0], side_b[0]), edge_of(side_a[0], side_b[1]),
             edge_of(side_a[1], side_b[1]), edge_of(side_a[1], side_b[0])};
  }
  // Orient the fan from a towards b.
  const auto point = [&](int k) {
    const auto& edge = tet_local::kEdges[static_cast<std::size_t>(k)];
    return crossing_point(corners, cut, edge[0], edge[1]);
  };
  Vec3 normal = Vec3::Zero();
  for (std::size_t m = 1; m + 1 < edges.size(); ++m) {
    normal += (point(edges[m]) - point(edges[0])).cross(point(edges[m + 1]) - point(edges[0]));
  }
  Vec3 centre_a = Vec3::Zero();
  Vec3 centre_b = Vec3::Zero();
  for (int k : side_a) {
    centre_a += corners[static_cast<std::size_t>(k)] / static_cast<double>(side_a.size());
  }
  for (int k : side_b) {
    centre_b += corners[static_cast<std::size_t>(k)] / static_cast<double>(side_b.size());
  }
  if (normal.dot(centre_b - centre_a) < 0.0) {
    std::reverse(edges.begin() + 1, edges.end());
  }
  return edges;
}

std::vector<Vec3> cut_polygon(const std::array<Vec3, 4>& corners, const ElementCut& cut) {
  std::vector<Vec3> polygon;
  for (int k : cut_polygon_edges(corners, cut)) {
    const auto& edge = tet_local::kEdges[static_cast<std::size_t>(k)];
    polygon.push_back(crossing_point(corners, cut, edge[0], edge[1]));
  }
  return polygon;
}

SideVolumes side_volumes(const std::array<Vec3, 4>& corners, const ElementCut& cut) {
  const Vec3& origin = corners[0];
  const double whole = signed_volume(corners[0], corners[1], corners[2], corners[3]);
  INCISE_ASSERT(whole > 0.0, "side volumes of a positive tetrahedron");
  if (!cut.splits()) {
    return cut.on_b[0] ? SideVolumes{0.0, whole} : SideVolumes{whole, 0.0};
  }
  // Region a is bounded by the side-a parts of the four faces (outward) and the cut surface
  // (oriented from a to b: outward for a).
  double six_a = fan_volume(origin, cut_polygon(corners, cut));
  for (const auto& face : tet_local::kFaces) {
    std::vector<Vec3> part;
    for (std::size_t m = 0; m < 3; ++m) {
      const int i = face[m];
      const int j = face[(m + 1) % 3];
      if (!cut.on_b[static_cast<std::size_t>(i)]) {
        part.push_back(corners[static_cast<std::size_t>(i)]);
      }
      if (cut.on_b[static_cast<std::size_t>(i)] != cut.on_b[static_cast<std::size_t>(j)]) {
        part.push_back(crossing_point(corners, cut, i, j));
      }
    }
    if (part.size() >= 3) {
      six_a += fan_volume(origin, part);
    }
  }
  const double a = std::clamp(six_a / 6.0, 0.0, whole);
  return {a, whole - a};
}

std::optional<ElementCut> cut_by_plane(const std::array<Vec3, 4>& corners, const Vec3& point,
                                       const Vec3& normal) {
  std::array<double, 4> height{};
  ElementCut cut;
  for (std::size_t k = 0; k < 4; ++k) {
    height[k] = (corners[k] - point).dot(normal);
    cut.on_b[k] = height[k] > 0.0;
  }
  if (!cut.splits()) {
    return std::nullopt;
  }
  for (std::size_t k = 0; k < 6; ++k) {
    const auto i = static_cast<std::size_t>(tet_local::kEdges[k][0]);
    const auto j = static_cast<std::size_t>(tet_local::kEdges[k][1]);
    if (cut.on_b[i] != cut.on_b[j]) {
      // A corner on the plane (height 0, side a) makes t = 0: nudge inside, the volume it
      // weighs is zero either way.
      cut.crossing[k] = std::clamp(height[i] / (height[i] - height[j]), 1e-12, 1.0 - 1e-12);
    }
  }
  return cut;
}

std::optional<ElementCut> cut_by_surface(const std::array<Vec3, 4>& corners,
                                         std::span<const std::array<Vec3, 3>> triangles,
                                         std::uint8_t* crossed) {
  std::uint8_t mask = 0;
  ElementCut cut;
  std::array<int, 4> votes_b{};  // per corner: crossed edges that put it on side b, minus a
  for (std::size_t k = 0; k < 6; ++k) {
    const auto i = static_cast<std::size_t>(tet_local::kEdges[k][0]);
    const auto j = static_cast<std::size_t>(tet_local::kEdges[k][1]);
    for (const auto& triangle : triangles) {
      if (!segment_intersects_triangle(corners[i], corners[j], triangle[0], triangle[1],
                                       triangle[2])) {
        continue;
      }
      const Vec3 normal = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]);
      const double hi = normal.dot(corners[i] - triangle[0]);
      const double hj = normal.dot(corners[j] - triangle[0]);
      if (hi == hj) {
        continue;  // the edge lies in the surface's plane: it crosses nothing
      }
      mask = static_cast<std::uint8_t>(mask | (1u << k));
      cut.crossing[k] = std::clamp(hi / (hi - hj), 1e-9, 1.0 - 1e-9);
      const int towards_j = hj > hi ? 1 : -1;  // the normal points from i to j
      votes_b[j] += towards_j;
      votes_b[i] -= towards_j;
      break;
    }
  }
  if (crossed != nullptr) {
    *crossed = mask;
  }
  // The seven ways to part four corners; the crossed edges must be exactly those between parts.
  constexpr std::array<std::array<bool, 4>, 7> kPartitions = {{{true, false, false, false},
                                                               {false, true, false, false},
                                                               {false, false, true, false},
                                                               {false, false, false, true},
                                                               {true, true, false, false},
                                                               {true, false, true, false},
                                                               {true, false, false, true}}};
  for (const auto& part : kPartitions) {
    std::uint8_t between = 0;
    for (std::size_t k = 0; k < 6; ++k) {
      if (part[static_cast<std::size_t>(tet_local::kEdges[k][0])] !=
          part[static_cast<std::size_t>(tet_local::kEdges[k][1])]) {
        between = static_cast<std::uint8_t>(between | (1u << k));
      }
    }
    if (between != mask) {
      continue;
    }
    int vote = 0;
    for (std::size_t c = 0; c < 4; ++c) {
      vote += part[c] ? votes_b[c] : -votes_b[c];
    }
    for (std::size_t c = 0; c < 4; ++c) {
      cut.on_b[c] = vote >= 0 ? part[c] : !part[c];
    }
    return cut;
  }
  return std::nullopt;
}

VirtualElements virtual_elements(const Tet& real, const ElementCut& cut, const Tet& copies) {
  VirtualElements elements{real, real};
  for (std::size_t k = 0; k < 4; ++k) {
    (cut.on_b[k] ? elements.a : elements.b)[k] = copies[k];
  }
  return elements;
}

}  // namespace incise
