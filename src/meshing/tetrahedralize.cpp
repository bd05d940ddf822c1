#include "incise/meshing/tetrahedralize.hpp"

#define TETLIBRARY
#include <tetgen.h>
#undef TETLIBRARY

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <iostream>
#include <map>
#include <numbers>
#include <numeric>
#include <sstream>

#include "cgal_surface.hpp"
#include "incise/core/child_process.hpp"
#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"

namespace incise {

bool SurfaceCheckReport::ok() const {
  return open_edges == 0 && nonmanifold_edges == 0 && misoriented_edges == 0 &&
         degenerate_triangles == 0 && self_intersections.empty();
}

std::string SurfaceCheckReport::describe() const {
  std::ostringstream out;
  if (open_edges > 0) {
    out << open_edges << " open edges (the surface has holes)\n";
  }
  if (nonmanifold_edges > 0) {
    out << nonmanifold_edges << " edges shared by more than two triangles\n";
  }
  if (misoriented_edges > 0) {
    out << misoriented_edges << " edges where neighbouring triangles disagree in orientation\n";
  }
  if (degenerate_triangles > 0) {
    out << degenerate_triangles << " degenerate triangles (repeated or collinear corners)\n";
  }
  if (!self_intersections.empty()) {
    out << "self-intersections, e.g. triangles";
    for (const auto& [a, b] : self_intersections) {
      out << " " << a << "/" << b;
    }
    out << "\n";
  }
  return out.str();
}

namespace {

using cgal_surface::CgalMesh;
using cgal_surface::Kernel;
using cgal_surface::to_cgal_mesh;

bool collinear(const Vec3& a, const Vec3& b, const Vec3& c) {
  return CGAL::collinear(Kernel::Point_3(a.x(), a.y(), a.z()), Kernel::Point_3(b.x(), b.y(), b.z()),
                         Kernel::Point_3(c.x(), c.y(), c.z()));
}

}  // namespace

SurfaceCheckReport check_closed_surface(const SurfaceMesh& surface) {
  SurfaceCheckReport report;
  const SurfaceEdgeCheck edges = check_surface_edges(surface.triangles);
  report.open_edges = edges.open_edges;
  report.nonmanifold_edges = edges.nonmanifold_edges;
  report.misoriented_edges = edges.misoriented_edges;
  report.degenerate_triangles = edges.degenerate_triangles;
  for (const Triangle& t : surface.triangles) {
    if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2] &&
        collinear(surface.points[t[0]], surface.points[t[1]], surface.points[t[2]])) {
      ++report.degenerate_triangles;
    }
  }
  if (!report.ok()) {
    return report;  // the self-intersection test needs a clean two-manifold
  }
  CgalMesh mesh = to_cgal_mesh(surface);
  std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(mesh, std::back_inserter(pairs));
  for (std::size_t i = 0; i < std::min<std::size_t>(pairs.size(), 10); ++i) {
    // Faces are created in soup order, so face indices are triangle indices.
    report.self_intersections.emplace_back(static_cast<std::size_t>(pairs[i].first),
                                           static_cast<std::size_t>(pairs[i].second));
  }
  return report;
}

namespace {

struct TetgenOutcome {
  std::vector<double> points;      ///< x, y, z per point
  std::vector<std::int32_t> tets;  ///< four corners per tetrahedron
  std::string error;               ///< empty on success
  bool timed_out = false;
  [[nodiscard]] bool ok() const { return error.empty(); }
};

std::string tetgen_error(int code) {
  switch (code) {
    case 1:
      return "TetGen ran out of memory";
    case 3:
      return "TetGen found a self-intersection in the surface";
    case 4:
      return "TetGen found a feature smaller than its tolerance";
    case 5:
      return "TetGen found two nearly coincident facets";
    default:
      return "TetGen failed (code " + std::to_string(code) + ") on this surface";
  }
}

/// Runs TetGen in the child process: writes [status, point count, tet count, points, tets].
[[noreturn]] void tetgen_child(const SurfaceMesh& surface, std::string switches, int fd) {
  std::int64_t header[3] = {0, 0, 0};
  try {
    tetgenio in;
    in.firstnumber = 0;
    in.numberofpoints = static_cast<int>(surface.points.size());
    in.pointlist = new REAL[surface.points.size() * 3];
    for (std::size_t i = 0; i < surface.points.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        in.pointlist[3 * i + k] = surface.points[i][k];
      }
    }
    in.numberoffacets = static_cast<int>(surface.triangles.size());
    in.facetlist = new tetgenio::facet[surface.triangles.size()];
    in.facetmarkerlist = new int[surface.triangles.size()];
    for (std::size_t f = 0; f < surface.triangles.size(); ++f) {
      tetgenio::facet& facet = in.facetlist[f];
      tetgenio::init(&facet);
      facet.numberofpolygons = 1;
      facet.polygonlist = new tetgenio::polygon[1];
      tetgenio::init(&facet.polygonlist[0]);
      facet.polygonlist[0].numberofvertices = 3;
      facet.polygonlist[0].vertexlist = new int[3];
      for (int k = 0; k < 3; ++k) {
        facet.polygonlist[0].vertexlist[k] = surface.triangles[f][k];
      }
      in.facetmarkerlist[f] = 1;
    }
    tetgenio out;
    tetrahedralize(switches.data(), &in, &out);
    if (out.numberoftetrahedra <= 0 || out.numberofcorners < 4) {
      header[0] = 100;
      write_all(fd, header, sizeof(header));
      ::_exit(0);
    }
    header[1] = out.numberofpoints;
    header[2] = out.numberoftetrahedra;
    std::vector<std::int32_t> corners(static_cast<std::size_t>(header[2]) * 4);
    for (std::size_t t = 0; t < static_cast<std::size_t>(header[2]); ++t) {
      for (int k = 0; k < 4; ++k) {
        corners[4 * t + static_cast<std::size_t>(k)] =
            out.tetrahedronlist[t * static_cast<std::size_t>(out.numberofcorners) +
                                static_cast<std::size_t>(k)];
      }
    }
    const bool sent =
        write_all(fd, header, sizeof(header)) &&
        write_all(fd, out.pointlist, sizeof(double) * 3 * static_cast<std::size_t>(header[1])) &&
        write_all(fd, corners.data(), sizeof(std::int32_t) * corners.size());
    ::_exit(sent ? 0 : 1);
  } catch (int code) {
    header[0] = code == 0 ? 2 : code;
  } catch (...) {
    header[0] = 101;
  }
  write_all(fd, header, sizeof(header));
  ::_exit(0);
}

/// TetGen 1.5.0 double-frees its memory after any internal error (terminatetetgen frees,
/// then the destructor frees again), and a pathological input could keep it busy for ever:
/// run it in a child process so a crash or a hang becomes an error message.
TetgenOutcome run_tetgen_isolated(const SurfaceMesh& surface, const std::string& switches,
                                  double timeout_seconds) {
  TetgenOutcome outcome;
  const ChildOutcome child =
      run_in_child([&](int fd) { tetgen_child(surface, switches, fd); }, timeout_seconds);
  if (!child.start_error.empty()) {
    outcome.error = "cannot start TetGen (" + child.start_error + ")";
    return outcome;
  }
  if (child.timed_out) {
    outcome.timed_out = true;
    outcome.error = fmt::format(
        "TetGen did not finish within {} s; the surface is probably "
        "self-intersecting or too finely detailed",
        timeout_seconds);
    return outcome;
  }
  const std::string& received = child.output;
  std::int64_t header[3] = {0, 0, 0};
  if (received.size() < sizeof(header)) {
    outcome.error = child.signal != 0
                        ? fmt::format(
                              "TetGen crashed (signal {}) on this surface: it could not "
                              "recover the boundary",
                              child.signal)
                        : "TetGen stopped without a result";
    return outcome;
  }
  std::memcpy(header, received.data(), sizeof(header));
  if (header[0] != 0) {
    outcome.error = header[0] == 100 ? "TetGen produced no tetrahedra from this surface"
                                     : tetgen_error(static_cast<int>(header[0]));
    return outcome;
  }
  const auto point_count = static_cast<std::size_t>(header[1]);
  const auto tet_count = static_cast<std::size_t>(header[2]);
  const std::size_t expected =
      sizeof(header) + point_count * 3 * sizeof(double) + tet_count * 4 * sizeof(std::int32_t);
  if (received.size() != expected || !child.exited_cleanly()) {
    outcome.error = "TetGen's result arrived incomplete";
    return outcome;
  }
  outcome.points.resize(point_count * 3);
  outcome.tets.resize(tet_count * 4);
  std::memcpy(outcome.points.data(), received.data() + sizeof(header),
              point_count * 3 * sizeof(double));
  std::memcpy(outcome.tets.data(),
              received.data() + sizeof(header) + point_count * 3 * sizeof(double),
              tet_count * 4 * sizeof(std::int32_t));
  return outcome;
}

}  // namespace

double min_triangle_angle_deg(const SurfaceMesh& surface) {
  double smallest = 180.0;
  for (const Triangle& t : surface.triangles) {
    for (int i = 0; i < 3; ++i) {
      const Vec3 u = surface.points[t[(i + 1) % 3]] - surface.points[t[i]];
      const Vec3 w = surface.points[t[(i + 2) % 3]] - surface.points[t[i]];
      const double denominator = u.norm() * w.norm();
      if (denominator == 0.0) {
        return 0.0;
      }
      smallest = std::min(smallest, std::acos(std::clamp(u.dot(w) / denominator, -1.0, 1.0)) *
                                        180.0 / std::numbers::pi);
    }
  }
  return smallest;
}

std::vector<SurfaceMesh> surface_shells(const SurfaceMesh& surface) {
  // Union-find over triangle corners.
  std::vector<VertexId> parent(surface.points.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](VertexId v) {
    while (parent[v] != v) {
      parent[v] = parent[parent[v]];
      v = parent[v];
    }
    return v;
  };
  for (const Triangle& t : surface.triangles) {
    parent[find(t[0])] = find(t[1]);
    parent[find(t[1])] = find(t[2]);
  }
  std::map<VertexId, std::size_t> shell_of_root;
  std::vector<SurfaceMesh> shells;
  std::vector<std::vector<VertexId>> remaps;
  for (const Triangle& t : surface.triangles) {
    const VertexId root = find(t[0]);
    auto [it, inserted] = shell_of_root.try_emplace(root, shells.size());
    if (inserted) {
      shells.emplace_back();
      remaps.emplace_back(surface.points.size(), kInvalidId);
    }
    SurfaceMesh& shell = shells[it->second];
    std::vector<VertexId>& remap = remaps[it->second];
    Triangle local{};
    for (int k = 0; k < 3; ++k) {
      if (remap[t[k]] == kInvalidId) {
        remap[t[k]] = static_cast<VertexId>(shell.points.size());
        shell.points.push_back(surface.points[t[k]]);
      }
      local[k] = remap[t[k]];
    }
    shell.triangles.push_back(local);
  }
  std::stable_sort(shells.begin(), shells.end(), [](const SurfaceMesh& a, const SurfaceMesh& b) {
    return a.triangles.size() > b.triangles.size();
  });
  return shells;
}

SurfaceMesh remesh_surface(const SurfaceMesh& surface, double edge_length) {
  if (!(edge_length > 0.0) || !std::isfinite(edge_length)) {
    throw InputError("remeshing edge length must be positive");
  }
  CgalMesh mesh = to_cgal_mesh(surface);
  CGAL::Polygon_mesh_processing::isotropic_remeshing(
      faces(mesh), edge_length, mesh,
      CGAL::parameters::number_of_iterations(5).number_of_relaxation_steps(3));
  return cgal_surface::from_cgal_mesh(std::move(mesh), "remeshing");
}

TetrahedralizeResult tetrahedralize(const SurfaceMesh& input,
                                    const TetrahedralizeOptions& options) {
  const SurfaceMesh* chosen = &input;
  SurfaceMesh remeshed;
  std::vector<std::string> notes;
  const SurfaceMesh& surface = input;
  if (surface.triangles.size() < 4) {
    throw InputError("a closed surface needs at least 4 triangles, this one has " +
                     std::to_string(surface.triangles.size()));
  }
  if (!(options.max_radius_edge_ratio >= 1.1) || !std::isfinite(options.max_radius_edge_ratio)) {
    throw InputError(fmt::format("radius-edge ratio bound {} is below 1.1; TetGen might not finish",
                                 options.max_radius_edge_ratio));
  }
  if (!(options.max_volume >= 0.0) || !std::isfinite(options.max_volume)) {
    throw InputError("maximum tetrahedron volume must be non-negative");
  }
  if (!(options.timeout_seconds > 0.0)) {
    throw InputError("the TetGen time limit must be positive");
  }
  if (!(options.min_dihedral_deg >= 0.0 && options.min_dihedral_deg <= 18.0)) {
    throw InputError("minimum dihedral angle must lie in [0, 18] degrees for TetGen to finish");
  }
  const SurfaceCheckReport check = check_closed_surface(surface);
  if (!check.ok()) {
    throw InputError("the surface cannot be tetrahedralised:\n" + check.describe());
  }
  const double needle = min_triangle_angle_deg(surface);
  using Remesh = TetrahedralizeOptions::Remesh;
  if (options.remesh == Remesh::kAlways ||
      (options.remesh == Remesh::kAuto && needle < options.needle_angle_deg)) {
    double length = options.remesh_edge_length;
    if (length <= 0.0) {
      std::vector<double> lengths;
      lengths.reserve(surface.triangles.size() * 3);
      for (const Triangle& t : surface.triangles) {
        for (int k = 0; k < 3; ++k) {
          lengths.push_back((surface.points[t[k]] - surface.points[t[(k + 1) % 3]]).norm());
        }
      }
      std::nth_element(lengths.begin(),
                       lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2),
                       lengths.end());
      length = lengths[lengths.size() / 2];
    }
    remeshed = remesh_surface(surface, length);
    const SurfaceCheckReport recheck = check_closed_surface(remeshed);
    if (!recheck.ok()) {
      throw InputError("the remeshed surface is not closed and clean:\n" + recheck.describe());
    }
    notes.push_back(fmt::format(
        "remeshed the surface to edge length {:.4g} ({} -> {} triangles; smallest angle {:.3g} -> "
        "{:.3g} deg)",
        length, surface.triangles.size(), remeshed.triangles.size(), needle,
        min_triangle_angle_deg(remeshed)));
    chosen = &remeshed;
  }

  // p: piecewise linear complex; q: quality bound; a: volume bound; Q: quiet; z: 0-based.
  std::string switches = fmt::format("pzQq{}", options.max_radius_edge_ratio);
  if (options.min_dihedral_deg > 0.0) {
    switches += fmt::format("/{}", options.min_dihedral_deg);
  }
  if (options.max_volume > 0.0) {
    switches += fmt::format("a{}", options.max_volume);
  }
  TetgenOutcome outcome = run_tetgen_isolated(
      *chosen, switches + (options.preserve_surface ? "Y" : ""), options.timeout_seconds);
  if (!outcome.ok() && !options.preserve_surface && !outcome.timed_out) {
    // TetGen 1.5 sometimes fails to recover boundary segments with Steiner points; keeping
    // the surface as given usually succeeds.
    TetgenOutcome retry = run_tetgen_isolated(*chosen, switches + "Y", options.timeout_seconds);
    if (retry.ok()) {
      notes.push_back("TetGen could not recover the boundary (" + outcome.error +
                      "); retried keeping the surface triangles as they are");
      outcome = std::move(retry);
    }
  }
  if (!outcome.ok()) {
    throw InputError(outcome.error);
  }
  std::vector<Vec3> positions(outcome.points.size() / 3);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    positions[i] =
        Vec3(outcome.points[3 * i], outcome.points[3 * i + 1], outcome.points[3 * i + 2]);
  }
  std::vector<Tet> tets(outcome.tets.size() / 4);
  for (std::size_t t = 0; t < tets.size(); ++t) {
    const std::int32_t* corners = outcome.tets.data() + 4 * t;
    Tet tet{corners[0], corners[1], corners[2], corners[3]};
    for (VertexId v : tet) {
      if (v < 0 || static_cast<std::size_t>(v) >= positions.size()) {
        throw InputError("TetGen returned an invalid tetrahedron");
      }
    }
    if (signed_volume(positions[tet[0]], positions[tet[1]], positions[tet[2]], positions[tet[3]]) <
        0.0) {
      std::swap(tet[2], tet[3]);
    }
    tets[t] = tet;
  }
  return {TetMesh(std::move(positions), std::move(tets)), std::move(notes)};
}

}  // namespace incise
