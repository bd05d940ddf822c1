#include "incise/meshing/repair_surface.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/stitch_borders.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/alpha_wrap_3.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>

#include "cgal_surface.hpp"
#include "incise/core/error.hpp"
#include "incise/meshing/tetrahedralize.hpp"

namespace incise {

namespace {

namespace PMP = CGAL::Polygon_mesh_processing;
using cgal_surface::CgalMesh;
using cgal_surface::Kernel;
using cgal_surface::Point;
using cgal_surface::points_of;
using cgal_surface::Soup;
using cgal_surface::triangles_of;

SurfaceMesh surface_of(CgalMesh mesh) {
  return cgal_surface::from_cgal_mesh(std::move(mesh), "surface repair");
}

double diagonal_of(const SurfaceMesh& surface) {
  Vec3 low = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 high = -low;
  for (const Vec3& p : surface.points) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  return surface.points.empty() ? 0.0 : (high - low).norm();
}

/// Largest distance from a vertex of `from` to the triangles of `to` (surface units). The
/// triangles are taken as a soup: `to` may be the broken input.
double largest_vertex_distance(const SurfaceMesh& from, const SurfaceMesh& to) {
  std::vector<Kernel::Triangle_3> triangles;
  triangles.reserve(to.triangles.size());
  for (const Triangle& t : to.triangles) {
    const auto at = [&](int k) {
      const Vec3& p = to.points[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])];
      return Point(p.x(), p.y(), p.z());
    };
    Kernel::Triangle_3 triangle(at(0), at(1), at(2));
    if (!triangle.is_degenerate()) {
      triangles.push_back(triangle);
    }
  }
  if (triangles.empty()) {
    return 0.0;
  }
  using Primitive =
      CGAL::AABB_triangle_primitive<Kernel, std::vector<Kernel::Triangle_3>::iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
  Tree tree(triangles.begin(), triangles.end());
  tree.accelerate_distance_queries();
  double largest = 0.0;
  for (const Vec3& p : from.points) {
    largest = std::max(largest, tree.squared_distance(Point(p.x(), p.y(), p.z())));
  }
  return std::sqrt(largest);
}

/// In place: soup repairs, orientation with non-manifold vertices split, stitching, holes.
SurfaceMesh repair_in_place(const SurfaceMesh& surface, SurfaceRepairReport& report) {
  std::vector<Point> points = points_of(surface);
  Soup soup = triangles_of(surface);
  const std::size_t points_before = points.size();
  const std::size_t triangles_before = soup.size();
  PMP::repair_polygon_soup(points, soup);
  // Isolated points are dropped too: count only what the triangles used.
  std::vector<char> used(points_before, 0);
  for (const Triangle& t : surface.triangles) {
    for (VertexId v : t) {
      used[static_cast<std::size_t>(v)] = 1;
    }
  }
  const auto used_before = static_cast<std::size_t>(std::count(used.begin(), used.end(), 1));
  report.points_merged = used_before > points.size() ? used_before - points.size() : 0;
  report.triangles_removed = triangles_before - soup.size();
  const std::size_t points_merged = points.size();
  PMP::orient_polygon_soup(points, soup);
  report.vertices_split = points.size() - points_merged;
  // Two triangles on the same three points, once opposite, are duplicates once oriented (the
  // points orientation split stay split: only triangles are merged).
  report.triangles_removed += PMP::merge_duplicate_polygons_in_polygon_soup(points, soup);
  if (!PMP::is_polygon_soup_a_polygon_mesh(soup)) {
    report.failure =
        "triangles that no orientation makes a surface (an edge shared by more "
        "than two of them after every other repair)";
    return {};
  }
  CgalMesh mesh;
  PMP::polygon_soup_to_polygon_mesh(points, soup, mesh);
  report.edges_stitched = PMP::stitch_borders(mesh);
  std::vector<CgalMesh::Halfedge_index> borders;
  PMP::extract_boundary_cycles(mesh, std::back_inserter(borders));
  for (const CgalMesh::Halfedge_index border : borders) {
    std::vector<CgalMesh::Face_index> added;
    PMP::triangulate_and_refine_hole(mesh, border, std::back_inserter(added),
                                     CGAL::Emptyset_iterator());
    double area = 0.0;
    for (const CgalMesh::Face_index face : added) {
      area += PMP::face_area(face, mesh);
    }
    ++report.holes_filled;
    report.hole_area += area;
    report.largest_hole_area = std::max(report.largest_hole_area, area);
  }
  if (CGAL::is_closed(mesh) && !PMP::does_self_intersect(mesh)) {
    const bool outward = PMP::is_outward_oriented(mesh);
    PMP::orient_to_bound_a_volume(mesh);
    report.reoriented = !outward;
  }
  return surface_of(std::move(mesh));
}

SurfaceMesh wrap(const SurfaceMesh& surface, const SurfaceRepairOptions& options,
                 SurfaceRepairReport& report) {
  const double diagonal = diagonal_of(surface);
  report.alpha = options.wrap_alpha > 0.0 ? options.wrap_alpha : diagonal / 100.0;
  report.offset = options.wrap_offset > 0.0 ? options.wrap_offset : diagonal / 1000.0;
  const std::vector<Point> points = points_of(surface);
  const Soup soup = triangles_of(surface);
  CgalMesh wrapped;
  CGAL::alpha_wrap_3(points, soup, report.alpha, report.offset, wrapped);
  report.wrapped = true;
  return surface_of(std::move(wrapped));
}

/// The volume a closed surface bounds, negative when it faces inward (surface units cubed).
double signed_enclosed_volume(const SurfaceMesh& surface) {
  double volume = 0.0;
  for (const Triangle& t : surface.triangles) {
    const Vec3& a = surface.points[static_cast<std::size_t>(t[0])];
    volume += a.dot(surface.points[static_cast<std::size_t>(t[1])].cross(
                  surface.points[static_cast<std::size_t>(t[2])])) /
              6.0;
  }
  return volume;
}

/// What the in-place repair left, on one line.
std::string left_after(const SurfaceCheckReport& after, const SurfaceRepairReport& report) {
  if (!report.failure.empty()) {
    return report.failure;
  }
  std::string text = after.describe();
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && text.back() == ' ') {
    text.pop_back();
  }
  return text;
}

}  // namespace

SurfaceMesh repair_surface(const SurfaceMesh& surface, const SurfaceRepairOptions& options,
                           SurfaceRepairReport& report) {
  using Mode = SurfaceRepairOptions::Mode;
  report = {};
  const SurfaceCheckReport check = check_closed_surface(surface);
  if (check.ok() && options.mode != Mode::kWrap) {
    if (signed_enclosed_volume(surface) >= 0.0) {
      return surface;
    }
    // Closed and consistent, but facing in (TetGen would fill the outside).
    SurfaceMesh turned = surface;
    for (Triangle& t : turned.triangles) {
      std::swap(t[1], t[2]);
    }
    report.changed = true;
    report.reoriented = true;
    report.notes.push_back("turned every triangle to face outward (the surface faced inward)");
    return turned;
  }
  if (options.mode == Mode::kNone) {
    throw InputError("the surface cannot be tetrahedralised:\n" + check.describe() +
                     "\n(--repair auto repairs it in place where it can and wraps it where it "
                     "cannot)");
  }
  SurfaceMesh result;
  SurfaceCheckReport after;
  if (options.mode != Mode::kWrap) {
    try {
      result = repair_in_place(surface, report);
    } catch (const std::exception& error) {  // a CGAL precondition the input breaks
      report.failure = std::string("a repair step refused it: ") + error.what();
    }
    if (!report.failure.empty()) {
      after.nonmanifold_edges = 1;  // not ok: what is left is said by the failure
    } else {
      after = check_closed_surface(result);
    }
    if (report.points_merged > 0) {
      report.notes.push_back(fmt::format("merged {} duplicate points", report.points_merged));
    }
    if (report.triangles_removed > 0) {
      report.notes.push_back(
          fmt::format("removed {} duplicate or degenerate triangles", report.triangles_removed));
    }
    if (report.vertices_split > 0) {
      report.notes.push_back(fmt::format(
          "split {} non-manifold vertices (one copy per fan of triangles)", report.vertices_split));
    }
    if (report.edges_stitched > 0) {
      report.notes.push_back(fmt::format("stitched {} border edges", report.edges_stitched));
    }
    if (report.holes_filled > 0) {
      report.notes.push_back(fmt::format(
          "filled {} holes (area {:.4g} in all, the largest {:.4g}; surface units squared)",
          report.holes_filled, report.hole_area, report.largest_hole_area));
    }
    if (report.reoriented) {
      report.notes.push_back("turned the triangles to face outward");
    }
  }
  if (options.mode == Mode::kWrap || (options.mode == Mode::kAuto && !after.ok())) {
    if (options.mode == Mode::kAuto) {
      report.notes.push_back("in place, the surface still has " + left_after(after, report) +
                             "; wrapped it instead");
      std::vector<std::string> notes = std::move(report.notes);
      report = {};
      report.notes = std::move(notes);
    }
    result = wrap(surface, options, report);
    after = check_closed_surface(result);
    report.notes.push_back(fmt::format(
        "alpha-wrapped the surface (alpha {:.4g}, offset {:.4g} surface units): {} triangles, "
        "closed, manifold, no self-intersection, lying about the offset outside the input",
        report.alpha, report.offset, result.triangles.size()));
  }
  if (!after.ok()) {
    throw InputError("the surface cannot be tetrahedralised:\n" + check.describe() +
                     "\nand in place it could not be repaired: what is left is " +
                     left_after(after, report) + "\n(--repair auto wraps it instead)");
  }
  report.changed = true;
  report.result_to_input = largest_vertex_distance(result, surface);
  report.input_to_result = largest_vertex_distance(surface, result);
  report.notes.push_back(fmt::format(
      "the result lies within {:.4g} of the input and the input within {:.4g} of the result "
      "(surface units, measured at vertices)",
      report.result_to_input, report.input_to_result));
  return result;
}

}  // namespace incise
