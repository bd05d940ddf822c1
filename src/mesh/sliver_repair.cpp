#include "incise/mesh/sliver_repair.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>
#include <utility>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/used_points.hpp"

namespace incise {

namespace {

bool on_boundary(const TetMesh& mesh, VertexId vertex) {
  for (TetId t : mesh.vertex_tets(vertex)) {
    const int local = mesh.local_index(t, vertex);
    const std::array<TetId, 4>& neighbours = mesh.tet_neighbors(t);
    for (int f = 0; f < 4; ++f) {
      if (f != local && neighbours[static_cast<std::size_t>(f)] < 0) {
        return true;  // a boundary face through the vertex
      }
    }
  }
  return false;
}

/// Whether moving `vertex` onto `target` keeps every tetrahedron that survives (those without
/// `target`) right side out and no thinner than `tolerance`.
bool collapse_keeps_shape(const TetMesh& mesh, VertexId vertex, VertexId target, double tolerance) {
  for (TetId t : mesh.vertex_tets(vertex)) {
    if (mesh.local_index(t, target) >= 0) {
      continue;  // removed by the collapse
    }
    std::array<Vec3, 4> corners{};
    const Tet& tet = mesh.tet(t);
    for (int k = 0; k < 4; ++k) {
      corners[static_cast<std::size_t>(k)] =
          tet[static_cast<std::size_t>(k)] == vertex
              ? mesh.rest_position(target)
              : mesh.rest_position(tet[static_cast<std::size_t>(k)]);
    }
    if (orient3d(corners[0], corners[1], corners[2], corners[3]) != Sign::kPositive ||
        normalized_volume(corners[0], corners[1], corners[2], corners[3]) < tolerance) {
      return false;
    }
  }
  return true;
}

/// Height (m) of `vertex` over the plane of the face of `tet` opposite it.
double height_over_opposite_face(const TetMesh& mesh, TetId tet, VertexId vertex) {
  const Tet& corners = mesh.tet(tet);
  const int local = mesh.local_index(tet, vertex);
  std::array<Vec3, 3> face{};
  int k = 0;
  for (int i = 0; i < 4; ++i) {
    if (i != local) {
      face[static_cast<std::size_t>(k++)] =
          mesh.rest_position(corners[static_cast<std::size_t>(i)]);
    }
  }
  const Vec3 normal = (face[1] - face[0]).cross(face[2] - face[0]);
  const double area2 = normal.norm();
  return area2 > 0.0 ? std::abs(normal.dot(mesh.rest_position(vertex) - face[0])) / area2
                     : (mesh.rest_position(vertex) - face[0]).norm();
}

/// Tries the edges of `tet`, shortest first, each way round: an interior vertex moves onto its
/// neighbour with the boundary exactly kept; a boundary vertex only when it stands less than
/// `flat_height` off the plane of the sliver's opposite face (the boundary then moves by no
/// more than that, which `boundary_shift` keeps the largest of).
bool collapse_one_edge(TetMesh& mesh, TetId tet, double tolerance, double& boundary_shift) {
  const Tet corners = mesh.tet(tet);
  double longest = 0.0;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      longest = std::max(longest, (mesh.rest_position(corners[static_cast<std::size_t>(i)]) -
                                   mesh.rest_position(corners[static_cast<std::size_t>(j)]))
                                      .norm());
    }
  }
  const double flat_height = 1e-3 * longest;
  std::vector<std::pair<double, std::pair<VertexId, VertexId>>> edges;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      const VertexId a = corners[static_cast<std::size_t>(i)];
      const VertexId b = corners[static_cast<std::size_t>(j)];
      const double length = (mesh.rest_position(a) - mesh.rest_position(b)).norm();
      edges.push_back({length, {a, b}});
      edges.push_back({length, {b, a}});
    }
  }
  std::sort(edges.begin(), edges.end());
  for (const auto& [length, edge] : edges) {
    const auto [vertex, target] = edge;
    const double height =
        on_boundary(mesh, vertex) ? height_over_opposite_face(mesh, tet, vertex) : 0.0;
    if (height > flat_height || !collapse_keeps_shape(mesh, vertex, target, tolerance)) {
      continue;
    }
    try {
      mesh.collapse_vertex(vertex, target);
      boundary_shift = std::max(boundary_shift, height);
      return true;
    } catch (const InputError&) {
      // The link condition fails for this edge (or a removed tetrahedron has no neighbour to
      // absorb it): try the next.
    }
  }
  return false;
}

std::pair<std::vector<TetId>, std::vector<TetId>> flat_and_slivers(
    const TetMesh& mesh, const ValidationOptions& options) {
  const ValidationReport report = validate(mesh, options);
  return {report.degenerate_tets, report.sliver_tets};
}

}  // namespace

SliverRepairResult fix_slivers(TetMesh& mesh, const ValidationOptions& options) {
  SliverRepairResult result;
  auto [flat, slivers] = flat_and_slivers(mesh, options);
  result.flat_before = flat.size();
  result.slivers_before = slivers.size();
  // A collapse renumbers tetrahedra (removal swaps with the last): look again after each.
  const std::size_t most = 4 * (flat.size() + slivers.size()) + 1;
  for (std::size_t round = 0; round < most && !(flat.empty() && slivers.empty()); ++round) {
    bool any = false;
    std::vector<TetId> pending = flat;
    pending.insert(pending.end(), slivers.begin(), slivers.end());
    for (TetId t : pending) {
      if (collapse_one_edge(mesh, t, options.degenerate_tolerance, result.boundary_shift)) {
        ++result.collapses;
        any = true;
        break;
      }
    }
    if (!any) {
      break;
    }
    std::tie(flat, slivers) = flat_and_slivers(mesh, options);
  }
  result.flat_after = flat.size();
  result.slivers_after = slivers.size();
  // Drop the vertices the collapses left without tetrahedra.
  std::vector<Vec3> points(mesh.rest_positions().begin(), mesh.rest_positions().end());
  std::vector<Tet> tets(mesh.tets().begin(), mesh.tets().end());
  (void)drop_unused_points(points, tets);
  std::vector<int> labels(mesh.tet_count());
  for (std::size_t t = 0; t < tets.size(); ++t) {
    labels[t] = mesh.tet_label(static_cast<TetId>(t));
  }
  mesh = TetMesh(std::move(points), std::move(tets), std::move(labels));
  return result;
}

}  // namespace incise
