// Meshing from Python: incise.mesh_surface (what `incise mesh` does: repair, remesh,
// tetrahedralise) and Mesh.fix_slivers (what `incise convert --fix-slivers` does).

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "arrays.hpp"
#include "bindings.hpp"
#include "incise/core/error.hpp"
#include "incise/mesh/sliver_repair.hpp"
#include "incise/meshing/repair_surface.hpp"
#include "incise/meshing/tetrahedralize.hpp"

namespace incise::python {
namespace {

template <typename Mode>
Mode choose(const std::string& key, const std::string& value,
            std::initializer_list<std::pair<const char*, Mode>> choices) {
  std::string names;
  for (const auto& [name, mode] : choices) {
    if (value == name) {
      return mode;
    }
    names += (names.empty() ? "" : ", ") + std::string(name);
  }
  throw InputError(key + ": \"" + value + "\" is none of " + names);
}

py::dict repair_dict(const SurfaceRepairReport& repaired) {
  py::dict out;
  out["changed"] = repaired.changed;
  out["points_merged"] = repaired.points_merged;
  out["triangles_removed"] = repaired.triangles_removed;
  out["vertices_split"] = repaired.vertices_split;
  out["edges_stitched"] = repaired.edges_stitched;
  out["holes_filled"] = repaired.holes_filled;
  out["hole_area"] = repaired.hole_area;
  out["largest_hole_area"] = repaired.largest_hole_area;
  out["reoriented"] = repaired.reoriented;
  out["wrapped"] = repaired.wrapped;
  out["alpha"] = repaired.alpha;
  out["offset"] = repaired.offset;
  out["result_to_input"] = repaired.result_to_input;
  out["input_to_result"] = repaired.input_to_result;
  out["notes"] = repaired.notes;
  return out;
}

}  // namespace

void bind_meshing(py::module_& module) {
  module.def(
      "mesh_surface",
      [](const py::object& surface, double max_volume, double min_quality, double min_dihedral,
         bool preserve_surface, const std::string& remesh, double edge_length, bool largest_shell,
         const std::string& repair, double wrap_alpha, double wrap_offset, double timeout) {
        SurfaceMesh input = surface_from(surface, "surface");
        if (!(max_volume >= 0.0) || !(min_quality >= 1.1) || !(min_dihedral >= 0.0) ||
            !(min_dihedral <= 18.0) || !(edge_length >= 0.0) || !(wrap_alpha >= 0.0) ||
            !(wrap_offset >= 0.0) || !(timeout > 0.0)) {
          throw InputError(
              "mesh_surface: max_volume, edge_length, wrap_alpha and wrap_offset must be 0 or "
              "more, min_quality at least 1.1, min_dihedral 0-18 degrees, timeout positive");
        }
        TetrahedralizeOptions options;
        options.max_volume = max_volume;
        options.max_radius_edge_ratio = min_quality;
        options.min_dihedral_deg = min_dihedral;
        options.preserve_surface = preserve_surface;
        options.remesh_edge_length = edge_length;
        options.timeout_seconds = timeout;
        options.remesh = choose<TetrahedralizeOptions::Remesh>(
            "remesh", remesh,
            {{"auto", TetrahedralizeOptions::Remesh::kAuto},
             {"always", TetrahedralizeOptions::Remesh::kAlways},
             {"never", TetrahedralizeOptions::Remesh::kNever}});
        SurfaceRepairOptions repair_options;
        repair_options.wrap_alpha = wrap_alpha;
        repair_options.wrap_offset = wrap_offset;
        using RepairMode = SurfaceRepairOptions::Mode;
        repair_options.mode = choose<RepairMode>("repair", repair,
                                                 {{"auto", RepairMode::kAuto},
                                                  {"in-place", RepairMode::kInPlace},
                                                  {"wrap", RepairMode::kWrap},
                                                  {"none", RepairMode::kNone}});
        SurfaceRepairReport repaired;
        TetrahedralizeResult result;
        std::size_t shells = 0;
        {
          py::gil_scoped_release release;
          const std::vector<SurfaceMesh> pieces = surface_shells(input);
          shells = pieces.size();
          if (largest_shell && pieces.size() > 1) {
            input = pieces.front();
          }
          input = repair_surface(input, repair_options, repaired);
          result = tetrahedralize(input, options);
        }
        py::dict report;
        report["shells"] = shells;
        report["repair"] = repair_dict(repaired);
        report["notes"] = result.notes;
        return py::make_tuple(std::make_shared<TetMesh>(std::move(result.mesh)), report);
      },
      py::arg("surface"), py::arg("max_volume") = 0.0, py::arg("min_quality") = 1.5,
      py::arg("min_dihedral") = 0.0, py::arg("preserve_surface") = false,
      py::arg("remesh") = "auto", py::arg("edge_length") = 0.0, py::arg("largest_shell") = false,
      py::arg("repair") = "auto", py::arg("wrap_alpha") = 0.0, py::arg("wrap_offset") = 0.0,
      py::arg("timeout") = 600.0,
      "Tetrahedralises a triangle surface as `incise mesh` does: surface (a file: OBJ, STL, "
      "PLY, OFF, VTK polydata; or (points, triangles) arrays) repaired first (repair: 'auto' "
      "repairs in place, then alpha-wraps what that cannot close; 'in-place', 'wrap', 'none'), "
      "remeshed where it has needles, then TetGen. Lengths in the surface's units: max_volume "
      "(their cube, 0: no bound), edge_length, wrap_alpha and wrap_offset (0: from the bounding "
      "box). Returns (Mesh, report): the report says what the repair changed (holes filled "
      "and their area, triangles removed, the largest distance from the input) and what was "
      "done to mesh it. The GIL is released meanwhile.");

  module.def(
      "_fix_slivers",
      [](const TetMesh& mesh) {
        auto repaired = std::make_shared<TetMesh>(mesh);
        SliverRepairResult result;
        {
          py::gil_scoped_release release;
          result = fix_slivers(*repaired);
        }
        py::dict report;
        report["flat_before"] = result.flat_before;
        report["slivers_before"] = result.slivers_before;
        report["collapses"] = result.collapses;
        report["flat_after"] = result.flat_after;
        report["slivers_after"] = result.slivers_after;
        report["boundary_shift"] = result.boundary_shift;
        return py::make_tuple(repaired, report);
      },
      py::arg("mesh"));
}

}  // namespace incise::python
