#include "incise/mesh/boundary.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <map>
#include <numeric>
#include <unordered_map>

#include "incise/mesh/disjoint_sets.hpp"

namespace incise {

std::vector<BoundaryFace> boundary_faces(const TetMesh& mesh) {
  std::vector<BoundaryFace> faces;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto id = static_cast<TetId>(t);
    const Tet& tet = mesh.tet(id);
    const auto& neighbors = mesh.tet_neighbors(id);
    for (int f = 0; f < 4; ++f) {
      if (neighbors[f] == kBoundaryFace) {
        const auto& face = tet_local::kFaces[f];
        faces.push_back({{tet[face[0]], tet[face[1]], tet[face[2]]}, id, f});
      }
    }
  }
  return faces;
}

std::vector<bool> lip_faces(const TetMesh& mesh, std::span<const BoundaryFace> faces) {
  // A face by its three rest positions, in sorted order (the two lips of a cut face each
  // other, so their corners run opposite ways).
  using Place = std::array<std::array<double, 3>, 3>;
  const auto place_of = [&](const BoundaryFace& face) {
    Place place{};
    for (std::size_t k = 0; k < 3; ++k) {
      const Vec3& p = mesh.rest_position(face.vertices[k]);
      place[k] = {p.x(), p.y(), p.z()};
    }
    std::sort(place.begin(), place.end());
    return place;
  };
  std::map<Place, int> count;
  for (const BoundaryFace& face : faces) {
    ++count[place_of(face)];
  }
  std::vector<bool> lips(faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    lips[f] = count[place_of(faces[f])] > 1;
  }
  return lips;
}

SurfaceEdgeCheck check_surface_edges(std::span<const Triangle> triangles) {
  // Per undirected edge: number of uses in each direction (low->high, high->low).
  struct Uses {
    int forward = 0;
    int backward = 0;
  };
  std::unordered_map<std::uint64_t, Uses> edges;
  edges.reserve(triangles.size() * 2);
  SurfaceEdgeCheck check;
  for (const Triangle& triangle : triangles) {
    if (triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]) {
      ++check.degenerate_triangles;
      continue;
    }
    for (int i = 0; i < 3; ++i) {
      const VertexId a = triangle[i];
      const VertexId b = triangle[(i + 1) % 3];
      Uses& uses = edges[edge_key(a, b)];
      (a < b ? uses.forward : uses.backward) += 1;
    }
  }
  for (const auto& [key, uses] : edges) {
    const int total = uses.forward + uses.backward;
    if (total == 1) {
      ++check.open_edges;
    } else if (total > 2) {
      ++check.nonmanifold_edges;
    } else if (uses.forward != 1) {
      ++check.misoriented_edges;
    }
  }
  return check;
}

bool is_watertight(std::span<const Triangle> triangles) {
  // Closed and consistently oriented: every edge is used as often from a to b as from b to a.
  // So the edges used upwards (a < b) and those used downwards, each as the key (smaller,
  // larger), are the same multiset. Two sorts of 64-bit keys: the viewer runs this on every
  // surface a cut changes, and sorting (smaller, larger, sign) triples took 1.6x as long. An
  // edge from a vertex to itself (a degenerate triangle) is its own reverse and is left out.
  std::vector<std::uint64_t> upwards;
  std::vector<std::uint64_t> downwards;
  upwards.reserve(3 * triangles.size() / 2 + 1);
  downwards.reserve(3 * triangles.size() / 2 + 1);
  for (const Triangle& t : triangles) {
    for (std::size_t k = 0; k < 3; ++k) {
      const VertexId a = t[k];
      const VertexId b = t[(k + 1) % 3];
      const auto key = [](VertexId low, VertexId high) {
        return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(low)) << 32) |
               static_cast<std::uint32_t>(high);
      };
      if (a < b) {
        upwards.push_back(key(a, b));
      } else if (b < a) {
        downwards.push_back(key(b, a));
      }
    }
  }
  if (upwards.size() != downwards.size()) {
    return false;  // an open rim, or neighbours that disagree on which side is out
  }
  std::sort(upwards.begin(), upwards.end());
  std::sort(downwards.begin(), downwards.end());
  return upwards == downwards;
}

double enclosed_volume(std::span<const Vec3> points, std::span<const Triangle> triangles) {
  double six = 0.0;
  for (const Triangle& t : triangles) {
    const Vec3& a = points[static_cast<std::size_t>(t[0])];
    const Vec3& b = points[static_cast<std::size_t>(t[1])];
    const Vec3& c = points[static_cast<std::size_t>(t[2])];
    six += a.dot(b.cross(c));
  }
  return six / 6.0;
}

SurfaceEdgeCheck check_boundary(const TetMesh& mesh) {
  const auto faces = boundary_faces(mesh);
  std::vector<Triangle> triangles;
  triangles.reserve(faces.size());
  for (const BoundaryFace& face : faces) {
    triangles.push_back(face.vertices);
  }
  return check_surface_edges(triangles);
}

std::vector<int> tet_components(const TetMesh& mesh, int* count) {
  std::vector<int> component(mesh.tet_count(), -1);
  int next = 0;
  std::vector<TetId> stack;
  for (std::size_t seed = 0; seed < mesh.tet_count(); ++seed) {
    if (component[seed] >= 0) {
      continue;
    }
    component[seed] = next;
    stack.push_back(static_cast<TetId>(seed));
    while (!stack.empty()) {
      const TetId t = stack.back();
      stack.pop_back();
      for (TetId neighbor : mesh.tet_neighbors(t)) {
        if (neighbor >= 0 && component[neighbor] < 0) {
          component[neighbor] = next;
          stack.push_back(neighbor);
        }
      }
    }
    ++next;
  }
  if (count != nullptr) {
    *count = next;
  }
  return component;
}

int pieces_by_vertices(const TetMesh& mesh) {
  // The corners of every tetrahedron are joined.
  DisjointSets sets(mesh.vertex_count());
  std::vector<char> used(mesh.vertex_count(), 0);
  for (const Tet& tet : mesh.tets()) {
    for (int k = 0; k < 4; ++k) {
      used[static_cast<std::size_t>(tet[k])] = 1;
      sets.join(tet[k], tet[0]);
    }
  }
  int pieces = 0;
  for (std::size_t v = 0; v < used.size(); ++v) {
    if (used[v] != 0 && sets.find(static_cast<VertexId>(v)) == static_cast<VertexId>(v)) {
      ++pieces;
    }
  }
  return pieces;
}

bool cut_kept_boundary(const SurfaceEdgeCheck& before, const SurfaceEdgeCheck& after) {
  return after.open_edges <= before.open_edges &&
         after.nonmanifold_edges <= before.nonmanifold_edges &&
         after.misoriented_edges <= before.misoriented_edges &&
         after.degenerate_triangles <= before.degenerate_triangles;
}

}  // namespace incise
