#pragma once
// Meshes with one sliver of each kind (positive volume, tiny normalised volume), glued onto a
// boundary face of a box grid so the mesh stays conforming: what meshers leave and users bring.

#include <string>
#include <utility>
#include <vector>

#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise::test {

/// The kinds of sliver, by where the fourth point lies against the face (a, b, c) it stands on,
/// `height` above it (m): over the face's middle (cap), next to a corner (needle: one edge
/// almost nothing), over an edge's middle (wedge), or out beyond an edge in the face's plane
/// (spire: four points almost in one plane, the classic sliver).
inline std::vector<std::string> sliver_kinds() {
  return {"cap", "needle", "wedge", "spire"};
}

/// A 3 x 2 x 2 grid (0.03 x 0.02 x 0.02 m, 5 tetrahedra per cell) with one sliver of `kind`
/// on the middle of its top, the last tetrahedron.
inline TetMesh grid_with_sliver(const std::string& kind, double height = 1e-9) {
  const TetMesh grid = make_box_grid({{3, 2, 2}, Vec3(0.03, 0.02, 0.02), Vec3::Zero(), 5});
  // The top face nearest the top's middle.
  const Vec3 middle(0.015, 0.01, 0.02);
  BoundaryFace best{};
  double nearest = 1e30;
  for (const BoundaryFace& face : boundary_faces(grid)) {
    Vec3 centre = Vec3::Zero();
    bool top = true;
    for (VertexId v : face.vertices) {
      centre += grid.rest_position(v) / 3.0;
      top = top && grid.rest_position(v).z() > 0.02 - 1e-12;
    }
    if (top && (centre - middle).norm() < nearest) {
      nearest = (centre - middle).norm();
      best = face;
    }
  }
  const Vec3& a = grid.rest_position(best.vertices[0]);
  const Vec3& b = grid.rest_position(best.vertices[1]);
  const Vec3& c = grid.rest_position(best.vertices[2]);
  const Vec3 up(0, 0, height);  // the face is outward (+z): the apex goes above it
  Vec3 apex = (a + b + c) / 3.0 + up;
  if (kind == "needle") {
    apex = a + 1e-6 * (b + c - 2.0 * a) + up;
  } else if (kind == "wedge") {
    apex = 0.5 * (a + b) + up;
  } else if (kind == "spire") {
    apex = 0.5 * (a + b) + 0.5 * (0.5 * (a + b) - c) + up;  // beyond edge a-b, in the plane
  }
  std::vector<Vec3> points(grid.rest_positions().begin(), grid.rest_positions().end());
  std::vector<Tet> tets(grid.tets().begin(), grid.tets().end());
  points.push_back(apex);
  // The outward face with the apex beyond it: positively oriented.
  tets.push_back({best.vertices[0], best.vertices[1], best.vertices[2],
                  static_cast<VertexId>(points.size() - 1)});
  return TetMesh(std::move(points), std::move(tets));
}

}  // namespace incise::test
