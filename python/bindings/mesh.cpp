// incise.Mesh: a tetrahedral mesh (rest positions, tetrahedra, region labels), immutable from
// Python, so the arrays it hands out view its memory for as long as they live.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "arrays.hpp"
#include "bindings.hpp"
#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/summary.hpp"
#include "incise/mesh/validate.hpp"

namespace incise::python {
namespace {

std::optional<double> length_unit(const std::optional<std::string>& unit) {
  if (!unit) {
    return std::nullopt;
  }
  if (*unit == "m") {
    return 1.0;
  }
  if (*unit == "cm") {
    return 1e-2;
  }
  if (*unit == "mm") {
    return 1e-3;
  }
  throw InputError("unit: \"" + *unit + "\" is none of m, cm, mm");
}

py::dict validation_dict(const ValidationReport& report) {
  py::dict out;
  out["valid"] = report.ok();
  out["usable"] = report.usable();
  out["nonfinite_vertices"] = report.nonfinite_vertices;
  out["inverted_tets"] = report.inverted_tets;
  out["degenerate_tets"] = report.degenerate_tets;
  out["sliver_tets"] = report.sliver_tets;
  out["nonmanifold_faces"] = report.nonmanifold_faces;
  out["overlapping_tets"] = report.overlapping_tets;
  out["duplicate_tets"] = report.duplicate_tets;
  out["unreferenced_vertices"] = report.unreferenced_vertices;
  out["description"] = report.describe();
  return out;
}

py::dict info_dict(const TetMesh& mesh) {
  const MeshSummary summary = summarize(mesh);
  const ValidationReport report = validate(mesh);
  py::dict out;
  out["vertices"] = mesh.vertex_count();
  out["tets"] = mesh.tet_count();
  out["edges"] = mesh.edge_count();
  out["volume"] = summary.volume;
  out["virtual_elements"] = summary.virtual_elements;
  out["min_tet_volume"] = summary.min_tet_volume;
  out["max_tet_volume"] = summary.max_tet_volume;
  const auto& [low, high] = summary.bounds;
  out["bounding_box"] = py::dict(py::arg("min") = py::make_tuple(low.x(), low.y(), low.z()),
                                 py::arg("max") = py::make_tuple(high.x(), high.y(), high.z()));
  py::list regions;
  for (const auto& [label, region] : summary.regions) {
    regions.append(py::dict(py::arg("label") = label, py::arg("tets") = region.tets,
                            py::arg("volume") = region.volume));
  }
  out["regions"] = regions;
  out["components"] = summary.components;
  out["boundary_triangles"] = summary.boundary_triangles;
  out["watertight"] = summary.watertight;
  out["inverted"] = report.inverted_tets.size();
  out["degenerate"] = report.degenerate_tets.size();
  out["slivers"] = report.sliver_tets.size();
  out["valid"] = report.usable();
  out["quality"] =
      py::dict(py::arg("min_dihedral_deg") = summary.quality.min_dihedral_deg,
               py::arg("mean_min_dihedral_deg") = summary.quality.mean_min_dihedral_deg,
               py::arg("max_aspect_ratio") = summary.quality.max_aspect_ratio,
               py::arg("mean_aspect_ratio") = summary.quality.mean_aspect_ratio);
  return out;
}

std::shared_ptr<TetMesh> mesh_from_arrays(const py::object& vertices, const py::object& tets,
                                          const py::object& labels, bool check) {
  std::vector<Vec3> points = points_from(vertices, "vertices");
  std::vector<Tet> elements = ids_from<4>(tets, points.size(), "tets");
  if (elements.empty()) {
    throw InputError("tets: a mesh needs at least one tetrahedron");
  }
  std::vector<int> region_labels = labels.is_none()
                                       ? std::vector<int>(elements.size(), 0)
                                       : labels_from(labels, elements.size(), "labels");
  for (std::size_t t = 0; t < elements.size(); ++t) {
    const Tet& tet = elements[t];
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        if (tet[a] == tet[b]) {
          throw InputError("tets: row " + std::to_string(t) + " uses vertex " +
                           std::to_string(tet[a]) + " twice");
        }
      }
    }
  }
  auto mesh =
      std::make_shared<TetMesh>(std::move(points), std::move(elements), std::move(region_labels));
  if (check) {
    const ValidationReport report = validate(*mesh);
    if (!report.usable()) {
      throw InputError("the mesh is not valid:\n" + report.describe());
    }
  }
  return mesh;
}

}  // namespace

void bind_mesh(py::module_& module) {
  module.def(
      "read_surface",
      [](const std::filesystem::path& path) {
        SurfaceMesh surface;
        {
          py::gil_scoped_release release;
          surface = read_surface(path);
        }
        const auto points = std::make_shared<std::vector<Vec3>>(std::move(surface.points));
        const auto triangles =
            std::make_shared<std::vector<Triangle>>(std::move(surface.triangles));
        return py::make_tuple(
            points_view(*points, keeper(points)),
            ids_view<3>(std::span<const Triangle>(*triangles), keeper(triangles)));
      },
      py::arg("path"),
      "Reads a triangle surface (OBJ, STL, PLY, OFF, VTK polydata): (points (n, 3) float64, "
      "triangles (k, 3) int32), coincident points merged.");
  py::class_<TetMesh, std::shared_ptr<TetMesh>>(
      module, "Mesh",
      "A tetrahedral mesh: rest positions (m, or the file's unit), tetrahedra (four vertex "
      "ids, positively oriented) and a region label per tetrahedron.\n\n"
      "Immutable from Python: `vertices`, `tets` and `labels` are read-only numpy views of its "
      "memory (no copy), valid as long as they live.")
      .def(py::init(&mesh_from_arrays), py::arg("vertices"), py::arg("tets"),
           py::arg("labels") = py::none(), py::arg("check") = true,
           "A mesh from arrays: vertices (n, 3) floats (m), tets (m, 4) integer ids into them, "
           "labels (m,) integers (default 0). With check (default) a mesh that cannot be "
           "simulated (inverted, flat, overlapping or duplicated tetrahedra, non-manifold faces) "
           "raises InputError naming the elements; slivers of positive volume are accepted.")
      .def_static(
          "read",
          [](const std::filesystem::path& path, const std::string& labels) {
            py::gil_scoped_release release;
            return std::make_shared<TetMesh>(read_tet_mesh(path, ReadOptions{labels}).mesh);
          },
          py::arg("path"), py::arg("labels") = "",
          "Reads a tetrahedral mesh (.msh, .vtu, .vtk, .mesh, .node/.ele, .off/.obj volumes "
          "are refused with a reason). `labels`: the VTK cell array to take as region labels "
          "(default: the first integer one). Points used by no tetrahedron are dropped.")
      .def_static(
          "box",
          [](const py::object& size, std::array<int, 3> cells, const py::object& origin,
             int tets_per_cell) {
            BoxGridOptions options;
            options.size = point_from(size, "size");
            options.cells = cells;
            options.origin = point_from(origin, "origin");
            options.tets_per_cell = tets_per_cell;
            return std::make_shared<TetMesh>(make_box_grid(options));
          },
          py::arg("size") = std::array<double, 3>{0.1, 0.1, 0.1},
          py::arg("cells") = std::array<int, 3>{10, 10, 10},
          py::arg("origin") = std::array<double, 3>{0.0, 0.0, 0.0}, py::arg("tets_per_cell") = 6,
          "A box of `size` (m) from `origin` (m, its lowest corner), `cells` cells along x, y, "
          "z, each split into 6 (or 5) tetrahedra.")
      .def(
          "write",
          [](const TetMesh& mesh, const std::filesystem::path& path,
             const std::optional<std::string>& unit) {
            const std::optional<double> unit_m = length_unit(unit);
            py::gil_scoped_release release;
            write_tet_mesh(path, mesh, unit_m);
          },
          py::arg("path"), py::arg("unit") = py::none(),
          "Writes by extension: .vtu (ParaView), .msh (Gmsh 4.1), .mesh (MEDIT), .obj (the "
          "boundary), .node/.ele (TetGen). `unit` ('m', 'cm' or 'mm') is written into a .vtu's "
          "field data.")
      .def(
          "validate", [](const TetMesh& mesh) { return validation_dict(validate(mesh)); },
          "Every problem, with the ids of the elements involved: a dict of lists, `valid` "
          "(nothing wrong), `usable` (nothing but slivers) and a `description` in words.")
      .def("info", &info_dict,
           "What `incise info --json` says: counts, volume (the mesh's unit cubed), bounding "
           "box, regions, components, watertightness, quality, validity.")
      .def_property_readonly(
          "vertices",
          [](const py::object& self) {
            return points_view(self.cast<const TetMesh&>().rest_positions(), self);
          },
          "(n, 3) float64 rest positions (m), read-only, no copy.")
      .def_property_readonly(
          "tets",
          [](const py::object& self) {
            return ids_view<4>(self.cast<const TetMesh&>().tets(), self);
          },
          "(m, 4) int32 vertex ids, read-only, no copy.")
      .def_property_readonly(
          "labels",
          [](const py::object& self) {
            return values_view<int>(self.cast<const TetMesh&>().tet_labels(), self);
          },
          "(m,) int32 region label per tetrahedron, read-only, no copy.")
      .def_property_readonly(
          "fractions",
          [](const py::object& self) {
            return values_view<double>(self.cast<const TetMesh&>().material_fractions(), self);
          },
          "(m,) float64 material fraction per tetrahedron: 1, or below 1 for the virtual "
          "elements of an XFEM cut (each holds that share of its tetrahedron's material).")
      .def(
          "boundary",
          [](const TetMesh& mesh) {
            const std::vector<BoundaryFace> faces = boundary_faces(mesh);
            py::array_t<std::int32_t> triangles(
                {static_cast<py::ssize_t>(faces.size()), py::ssize_t{3}});
            auto out = triangles.mutable_unchecked<2>();
            for (std::size_t f = 0; f < faces.size(); ++f) {
              for (int k = 0; k < 3; ++k) {
                out(static_cast<py::ssize_t>(f), k) = faces[f].vertices[k];
              }
            }
            return triangles;
          },
          "(k, 3) int32: the boundary triangles, outward, as vertex ids.")
      .def_property_readonly("vertex_count", &TetMesh::vertex_count)
      .def_property_readonly("tet_count", &TetMesh::tet_count)
      .def_property_readonly(
          "volume", [](const TetMesh& mesh) { return total_volume(mesh); },
          "Rest volume (the mesh's unit cubed; m^3 for a mesh in metres).")
      .def("__repr__", [](const TetMesh& mesh) {
        return "<incise.Mesh " + std::to_string(mesh.vertex_count()) + " vertices, " +
               std::to_string(mesh.tet_count()) + " tetrahedra>";
      });
}

}  // namespace incise::python
