// incise.plan's compiled half: a plan (a file or a dict with the plan keys) run into a folder,
// its summary and the skin before and after as arrays. The Python half (incise/__init__.py)
// adds the report and the bone surfaces the run wrote.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "arrays.hpp"
#include "bindings.hpp"
#include "incise/planning/plan.hpp"

namespace incise::python {

void bind_planning(py::module_& module) {
  module.def(
      "_run_plan",
      [](const py::object& plan, const std::optional<std::filesystem::path>& plan_file,
         const std::filesystem::path& out_dir, const py::object& progress) {
        planning::PlanDescription description;
        if (py::isinstance<py::dict>(plan)) {
          const std::string text =
              py::module_::import("json").attr("dumps")(plan).cast<std::string>();
          description = planning::parse_plan(text, plan_file.value_or("<plan dict>"));
        } else {
          const auto path = plan.cast<std::filesystem::path>();
          description = planning::load_plan(path);
        }
        planning::PlanProgress report_progress;
        if (!progress.is_none()) {
          // Called from the planning thread without the GIL: take it for the callback.
          report_progress = [&progress](const std::string& stage, double fraction) {
            const py::gil_scoped_acquire acquire;
            progress(stage, fraction);
          };
        }
        planning::PlanSummary summary;
        {
          py::gil_scoped_release release;
          summary = planning::run_plan(description, out_dir, report_progress);
        }
        py::dict out;
        out["points"] = summary.points;
        out["springs"] = summary.springs;
        out["prisms"] = summary.prisms;
        out["segments"] = summary.segments;
        out["moved_segments"] = summary.moved_segments;
        out["residual_force_before"] = summary.residual_force_before;
        out["residual_force_after"] = summary.residual_force_after;
        out["max_displacement_mm"] = summary.max_displacement;
        out["seconds"] = summary.seconds;
        out["report_path"] = summary.report;
        py::array_t<std::int32_t> triangles(
            {static_cast<py::ssize_t>(summary.skin_triangles.size()), py::ssize_t{3}});
        std::copy_n(
            summary.skin_triangles.empty() ? nullptr : summary.skin_triangles.front().data(),
            3 * summary.skin_triangles.size(), triangles.mutable_data());
        out["skin_triangles"] = triangles;
        const auto before = std::make_shared<std::vector<Vec3>>(std::move(summary.skin_before));
        const auto after = std::make_shared<std::vector<Vec3>>(std::move(summary.skin_after));
        out["skin_before"] = points_view(*before, keeper(before));
        out["skin_after"] = points_view(*after, keeper(after));
        return out;
      },
      py::arg("plan"), py::arg("plan_file"), py::arg("out_dir"), py::arg("progress"));
}

}  // namespace incise::python
