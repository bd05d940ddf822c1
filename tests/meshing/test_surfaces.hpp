#pragma once
// Closed surfaces for the meshing tests: a box's boundary, and surfaces put together.

#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"

namespace incise::test {

/// The volume a closed, outward-oriented surface bounds (its units cubed).
inline double enclosed_volume(const SurfaceMesh& surface) {
  double volume = 0.0;
  for (const Triangle& t : surface.triangles) {
    volume += surface.points[t[0]].dot(surface.points[t[1]].cross(surface.points[t[2]])) / 6.0;
  }
  return volume;
}

/// The boundary of a box grid as a closed surface.
inline SurfaceMesh box_surface(const Vec3& origin = Vec3::Zero(), double size = 1.0) {
  BoxGridOptions options;
  options.cells = {2, 2, 2};
  options.origin = origin;
  options.size = Vec3(size, size, size);
  const TetMesh box = make_box_grid(options);
  SurfaceMesh surface;
  surface.points.assign(box.rest_positions().begin(), box.rest_positions().end());
  for (const BoundaryFace& face : boundary_faces(box)) {
    surface.triangles.push_back(face.vertices);
  }
  return surface;
}

/// Adds another surface's points and triangles to `into`.
inline void append_surface(SurfaceMesh& into, const SurfaceMesh& other) {
  const auto offset = static_cast<VertexId>(into.points.size());
  into.points.insert(into.points.end(), other.points.begin(), other.points.end());
  for (Triangle t : other.triangles) {
    for (VertexId& v : t) {
      v += offset;
    }
    into.triangles.push_back(t);
  }
}

}  // namespace incise::test
