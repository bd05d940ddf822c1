#pragma once
// incise's triangle surfaces as CGAL halfedge meshes and back: the one conversion the meshing
// module's CGAL code (tetrahedralisation checks, remeshing, repair) shares. Private to the
// module.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <array>
#include <string>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::cgal_surface {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalMesh = CGAL::Surface_mesh<Point>;
using Soup = std::vector<std::array<std::size_t, 3>>;

inline std::vector<Point> points_of(const SurfaceMesh& surface) {
  std::vector<Point> points;
  points.reserve(surface.points.size());
  for (const Vec3& p : surface.points) {
    points.emplace_back(p.x(), p.y(), p.z());
  }
  return points;
}

inline Soup triangles_of(const SurfaceMesh& surface) {
  Soup soup;
  soup.reserve(surface.triangles.size());
  for (const Triangle& t : surface.triangles) {
    soup.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]),
                    static_cast<std::size_t>(t[2])});
  }
  return soup;
}

/// A clean (closed, manifold, oriented) triangle surface as a CGAL halfedge mesh; faces keep
/// the triangles' order, so face index == triangle index.
inline CgalMesh to_cgal_mesh(const SurfaceMesh& surface) {
  CgalMesh mesh;
  CGAL::Polygon_mesh_processing::polygon_soup_to_polygon_mesh(points_of(surface),
                                                              triangles_of(surface), mesh);
  return mesh;
}

/// Back to points and triangles (garbage collected first); `operation` names what made the
/// mesh, for the error when a face is not a triangle.
inline SurfaceMesh from_cgal_mesh(CgalMesh mesh, const std::string& operation) {
  mesh.collect_garbage();
  SurfaceMesh surface;
  surface.points.reserve(mesh.number_of_vertices());
  for (const auto vertex : mesh.vertices()) {
    const Point& p = mesh.point(vertex);
    surface.points.emplace_back(p.x(), p.y(), p.z());
  }
  for (const auto face : mesh.faces()) {
    Triangle triangle{};
    int k = 0;
    for (const auto vertex : CGAL::vertices_around_face(mesh.halfedge(face), mesh)) {
      if (k < 3) {
        triangle[static_cast<std::size_t>(k)] = static_cast<VertexId>(vertex.idx());
      }
      ++k;
    }
    if (k != 3) {
      throw InternalError(operation + " produced a face that is not a triangle");
    }
    surface.triangles.push_back(triangle);
  }
  return surface;
}

}  // namespace incise::cgal_surface
