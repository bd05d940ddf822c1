// incise.cut's compiled half: a mesh cut along a blade path without physics, as `incise cut`
// does (the same cutters, checks, outputs and report).

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>

#include "arrays.hpp"
#include "bindings.hpp"
#include "incise/batch/xfem_path_cut.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/blade.hpp"
#include "incise/cut/path_cut.hpp"

namespace incise::python {
namespace {

/// An (n, 7) array of poses (t in s, tip x y z, base x y z), checked: finite, in time order.
std::vector<BladePose> blade_path_from(const py::object& poses) {
  const auto rows = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(poses);
  if (!rows || rows.ndim() != 2 || rows.shape(1) != 7 || rows.shape(0) < 1) {
    throw InputError("blade: an (n, 7) array of poses (t, tip x y z, base x y z) is needed");
  }
  std::vector<BladePose> path(static_cast<std::size_t>(rows.shape(0)));
  for (std::size_t i = 0; i < path.size(); ++i) {
    const double* row = rows.data() + 7 * i;
    path[i] = {row[0], Vec3(row[1], row[2], row[3]), Vec3(row[4], row[5], row[6])};
    if (!std::isfinite(row[0]) || !path[i].tip.allFinite() || !path[i].base.allFinite()) {
      throw InputError("blade: pose " + std::to_string(i) + " is not finite");
    }
    if (i > 0 && !(row[0] >= path[i - 1].time)) {
      throw InputError("blade: pose " + std::to_string(i) + " goes back in time");
    }
  }
  return path;
}

}  // namespace

void bind_cutting(py::module_& module) {
  module.def(
      "read_blade_path",
      [](const std::filesystem::path& path) {
        const std::vector<BladePose> poses = read_blade_path(path);
        py::array_t<double> rows({static_cast<py::ssize_t>(poses.size()), py::ssize_t{7}});
        auto out = rows.mutable_unchecked<2>();
        for (std::size_t i = 0; i < poses.size(); ++i) {
          const auto r = static_cast<py::ssize_t>(i);
          out(r, 0) = poses[i].time;
          for (int k = 0; k < 3; ++k) {
            out(r, 1 + k) = poses[i].tip[k];
            out(r, 4 + k) = poses[i].base[k];
          }
        }
        return rows;
      },
      py::arg("path"),
      "Reads a blade-path CSV (t,tip_x,tip_y,tip_z,base_x,base_y,base_z; s, m) as an (n, 7) "
      "array, as `incise cut --blade` and the scenes' tool.blade_path read it.");
  module.def(
      "_cut_subdivision",
      [](const TetMesh& mesh, const py::object& poses, double snap, const std::string& split,
         bool merge_blade_points, const std::string& mesh_name, const std::string& blade_name,
         const std::string& unit_name) {
        const std::vector<BladePose> path = blade_path_from(poses);
        if (!(snap >= 0.001 && snap <= 0.49)) {
          throw InputError("snap: must lie in [0.001, 0.49]");
        }
        if (split != "minimal" && split != "generic") {
          throw InputError("split: \"" + split + "\" is neither minimal nor generic");
        }
        CutterOptions options;
        options.snap_fraction = snap;
        options.split = split == "generic" ? SplitMode::kGeneric : SplitMode::kMinimal;
        options.merge_blade_points = merge_blade_points;
        auto cut = std::make_shared<TetMesh>(mesh);
        PathCutResult result;
        {
          py::gil_scoped_release release;
          result = cut_along_path(*cut, path, options, mesh_name, blade_name, unit_name);
        }
        return py::make_tuple(cut, result.report_json, result.invalid_poses, result.first_problem);
      },
      py::arg("mesh"), py::arg("poses"), py::arg("snap"), py::arg("split"),
      py::arg("merge_blade_points"), py::arg("mesh_name"), py::arg("blade_name"),
      py::arg("unit_name"));
  module.def(
      "_cut_xfem",
      [](const TetMesh& mesh, const py::object& poses, const py::object& visual,
         const std::filesystem::path& output, const std::filesystem::path& visual_out,
         std::optional<double> length_unit_m, const std::string& mesh_name,
         const std::string& blade_name) {
        XfemPathCutRequest request;
        request.output = output;
        request.visual_out = visual_out;
        request.length_unit_m = length_unit_m;
        request.mesh_name = mesh_name;
        request.blade_name = blade_name;
        if (!visual.is_none()) {
          request.visual = surface_from(visual, "visual");
        }
        const std::vector<BladePose> path = blade_path_from(poses);
        XfemPathCutResult result;
        {
          py::gil_scoped_release release;
          result = cut_xfem_along_path(mesh, path, request);
        }
        return result.report_json;
      },
      py::arg("mesh"), py::arg("poses"), py::arg("visual"), py::arg("output"),
      py::arg("visual_out"), py::arg("length_unit_m"), py::arg("mesh_name"), py::arg("blade_name"));
}

}  // namespace incise::python
