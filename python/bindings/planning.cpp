// incise.plan's compiled half: a plan (a file or a dict with the plan keys) run into a folder,
// its summary and the skin before and after as arrays. The Python half (incise/__init__.py)
// adds the report and the bone surfaces the run wrote. And incise.PlanSession: a plan
// prepared once, bone segments moved and the face predicted after each move.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>

#include "arrays.hpp"
#include "bindings.hpp"
#include "incise/core/error.hpp"
#include "incise/planning/plan.hpp"
#include "incise/planning/plan_session.hpp"

namespace incise::python {

namespace {

using planning::kMillimetre;

planning::PlanDescription describe(const py::object& plan,
                                   const std::optional<std::filesystem::path>& plan_file) {
  if (py::isinstance<py::dict>(plan)) {
    const std::string text = py::module_::import("json").attr("dumps")(plan).cast<std::string>();
    return planning::parse_plan(text, plan_file.value_or("<plan dict>"));
  }
  return planning::load_plan(plan.cast<std::filesystem::path>());
}

/// A session and the lock that keeps it to one thread at a time: its methods release the GIL
/// while they work, so a second Python thread may call it meanwhile and waits here.
struct PySession {
  std::mutex mutex;
  std::unique_ptr<planning::PlanSession> session;
};

/// Runs `work` on the session without the GIL and under its lock; returns what it returns.
template <typename Work>
auto locked(PySession& s, Work&& work) {
  const py::gil_scoped_release release;
  const std::lock_guard lock(s.mutex);
  return work(*s.session);
}

py::array copy_points(std::vector<Vec3> points) {
  const auto held = std::make_shared<std::vector<Vec3>>(std::move(points));
  return points_view(*held, keeper(held));
}

/// A progress callback for planning's own thread, which runs without the GIL: it takes the GIL
/// for the Python callable (none when `progress` is None).
planning::PlanProgress progress_with_gil(const py::object& progress) {
  if (progress.is_none()) {
    return {};
  }
  return [&progress](const std::string& stage, double fraction) {
    const py::gil_scoped_acquire acquire;
    progress(stage, fraction);
  };
}

}  // namespace

void bind_planning(py::module_& module) {
  py::class_<PySession>(
      module, "PlanSession",
      "A plan prepared once (surfaces, bone segments, the layered tissue balanced in its "
      "scanned state), then bone segments moved one after another and the face predicted "
      "after each, from the last prediction: interactive planning (what incise plan --view "
      "drives). Lengths in mm at this interface, positions returned in m. One call at a time "
      "(the GIL is released while it works; a second thread waits).")
      .def(
          py::init([](const py::object& plan, const std::optional<std::filesystem::path>& plan_file,
                      const py::object& progress) {
            const planning::PlanDescription description = describe(plan, plan_file);
            const planning::PlanProgress report = progress_with_gil(progress);
            auto holder = std::make_unique<PySession>();
            const py::gil_scoped_release release;
            holder->session = std::make_unique<planning::PlanSession>(description, report);
            return holder;
          }),
          py::arg("plan"), py::arg("plan_file") = py::none(), py::arg("progress") = py::none(),
          "Prepares the plan (a file's path or a dict with its keys; plan_file names a dict's "
          "file for errors and relative paths) with its own moves; progress(stage, fraction) "
          "is called meanwhile. Raises InputError as incise plan does.")
      .def_property_readonly(
          "segments",
          [](PySession& s) {
            return locked(s, [](planning::PlanSession& p) { return p.segments().count; });
          },
          "How many bone segments the osteotomies made.")
      .def_property_readonly(
          "segment_volumes_mm3",
          [](PySession& s) {
            return locked(s, [](planning::PlanSession& p) {
              std::vector<double> volumes;
              for (const double v : p.segments().volumes) {
                volumes.push_back(v / std::pow(kMillimetre, 3));
              }
              return volumes;
            });
          },
          "Each segment's volume (mm^3).")
      .def(
          "segment_near",
          [](PySession& s, const py::handle& point_mm) {
            const Vec3 point = point_from(point_mm, "point_mm") * kMillimetre;
            return locked(s, [&](planning::PlanSession& p) { return p.segment_near(point); });
          },
          py::arg("point_mm"), "The segment whose surface passes nearest this point (mm).")
      .def(
          "move",
          [](PySession& s, int segment, const py::handle& translate_mm, const py::handle& axis,
             double angle_deg, const py::object& center_mm) {
            planning::RigidMove move;
            move.translation = point_from(translate_mm, "translate_mm") * kMillimetre;
            move.axis = point_from(axis, "axis");
            if (!(move.axis.norm() > 0.0) || !std::isfinite(angle_deg)) {
              throw InputError("move: the axis must not be zero and the angle finite");
            }
            move.angle = angle_deg * 3.14159265358979323846 / 180.0;
            const bool centre_given = !center_mm.is_none();
            if (centre_given) {
              move.center = point_from(center_mm, "center_mm") * kMillimetre;
            }
            const std::vector<planning::Interpenetration> contact =
                locked(s, [&](planning::PlanSession& p) {
                  if (segment < 0 || segment >= p.segments().count) {
                    throw InputError("move: no bone segment " + std::to_string(segment) +
                                     " (the bone has " + std::to_string(p.segments().count) + ")");
                  }
                  if (!centre_given) {
                    move.center = p.segment_centre(segment);
                  }
                  return p.try_move(segment, move);
                });
            py::list out;
            for (const planning::Interpenetration& c : contact) {
              py::dict item;
              item["segments"] = py::make_tuple(c.first, c.second);
              item["crossing_triangle_pairs"] = c.crossing_triangle_pairs;
              item["depth_mm"] = c.depth / kMillimetre;
              out.append(item);
            }
            return out;
          },
          py::arg("segment"), py::arg("translate_mm") = py::make_tuple(0.0, 0.0, 0.0),
          py::arg("axis") = py::make_tuple(0.0, 0.0, 1.0), py::arg("angle_deg") = 0.0,
          py::arg("center_mm") = py::none(),
          "Sets the segment's move (a translation in mm after a rotation of angle_deg about axis "
          "through center_mm, by default the segment's centre), replacing its last one, unless "
          "the segments would then interpenetrate: returns the pairs that would (each a dict: "
          "segments, crossing_triangle_pairs, depth_mm); an empty list means the move is made.")
      .def(
          "predict",
          [](PySession& s, bool warm) {
            double residual = 0.0;
            const planning::MinimizeResult result = locked(s, [&](planning::PlanSession& p) {
              planning::MinimizeResult r = p.predict(warm);
              residual = p.residual_force();
              return r;
            });
            py::dict out;
            out["converged"] = result.converged;
            out["iterations"] = result.iterations;
            out["seconds"] = result.seconds;
            out["message"] = result.message;
            out["residual_force"] = residual;
            out["factorizations"] = result.factorizations;
            out["lagged_steps"] = result.lagged_steps;
            out["steps"] = py::module_::import("json").attr("loads")(
                planning::newton_steps_report(result.newton_steps).dump());
            out["pattern_analyses"] = result.pattern_analyses;
            out["stage_seconds"] = py::dict(py::arg("assembly") = result.assembly_seconds,
                                            py::arg("factorization") = result.factorization_seconds,
                                            py::arg("solve") = result.solve_seconds,
                                            py::arg("line_search") = result.line_search_seconds);
            return out;
          },
          py::arg("warm") = true,
          "Predicts the soft tissue for the moves made: from the last prediction (warm) or from "
          "the scanned state (what incise plan computes). Returns converged, iterations (Newton "
          "steps), seconds, message, residual_force (N), factorizations, lagged_steps (steps "
          "solved with an earlier factorisation, kept between predictions), steps (each Newton "
          "step: lagged_iterations and lagged_budget, its conjugate gradients with the factor in "
          "hand and the most allowed; lagged, convexified, factorized; step_length; gradient, the "
          "largest free point's gradient after it, N), pattern_analyses (analyses of the Hessian's "
          "pattern: 0 once the session's equilibrium or an earlier prediction made one) and "
          "stage_seconds (assembly, factorization, solve, line_search: where the time went).")
      .def(
          "prepare_next_nudge",
          [](PySession& s) {
            const auto start = std::chrono::steady_clock::now();
            locked(s, [](planning::PlanSession& p) { p.prepare_next_nudge(); });
            return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          },
          "Factorises the tissue's Hessian where the last prediction left it, so that the next "
          "warm prediction needs no factorisation of its own; returns the seconds it took. What "
          "the planning viewer does after showing each prediction, while the hand moves to the "
          "next nudge: called after every prediction, the predictions stay the same, bit for "
          "bit (the GIL is released meanwhile).")
      .def_property_readonly(
          "skin_triangles",
          [](PySession& s) {
            const auto triangles =
                std::make_shared<std::vector<Triangle>>(locked(s, [](planning::PlanSession& p) {
                  return std::vector<Triangle>(p.skin_triangles().begin(),
                                               p.skin_triangles().end());
                }));
            return ids_view<3>(*triangles, keeper(triangles));
          },
          "The skin's triangles (k, 3) over skin_before / skin_after's points.")
      .def_property_readonly(
          "skin_before",
          [](PySession& s) {
            return copy_points(locked(s, [](planning::PlanSession& p) { return p.skin_before(); }));
          },
          "The skin as scanned (n, 3), m.")
      .def_property_readonly(
          "skin_after",
          [](PySession& s) {
            return copy_points(locked(s, [](planning::PlanSession& p) { return p.skin_after(); }));
          },
          "The skin as last predicted (n, 3), m (as scanned before any prediction).")
      .def(
          "plan_with_moves",
          [](PySession& s, const py::dict& original) {
            const py::module_ json = py::module_::import("json");
            const std::string text = json.attr("dumps")(original).cast<std::string>();
            const std::string saved = locked(s, [&](planning::PlanSession& p) {
              return p.plan_with_moves(nlohmann::json::parse(text)).dump();
            });
            return json.attr("loads")(saved);
          },
          py::arg("plan"),
          "The plan (a dict) with the moves made in place of its own: incise plan runs it to "
          "the cold prediction.");

  module.def(
      "_run_plan",
      [](const py::object& plan, const std::optional<std::filesystem::path>& plan_file,
         const std::filesystem::path& out_dir, const py::object& progress) {
        const planning::PlanDescription description = describe(plan, plan_file);
        const planning::PlanProgress report_progress = progress_with_gil(progress);
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
