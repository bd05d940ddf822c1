// Running a plan: surfaces in, layered tissue built and balanced, bone cut and moved, the
// soft tissue predicted, everything written for ParaView and 3D Slicer.

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/meshing/tetrahedralize.hpp"
#include "incise/planning/decimate.hpp"
#include "incise/planning/equilibrium.hpp"
#include "incise/planning/newton.hpp"
#include "incise/planning/plan.hpp"
#include "incise/planning/plan_session.hpp"
#include "incise/planning/prism.hpp"
#include "incise/planning/tissue_energy.hpp"
#include "plan_surfaces.hpp"
#include "tissue_output.hpp"

namespace incise::planning {

PlanSummary run_plan(const PlanDescription& plan, const std::filesystem::path& out_dir,
                     const PlanProgress& progress) {
  const auto start = Clock::now();
  auto report_progress = [&](const std::string& stage, double fraction) {
    if (progress) {
      progress(stage, fraction);
    }
  };
  PlanSession session(plan, progress);
  report_progress("predicting the soft tissue", 0.5);
  auto stage = Clock::now();
  const MinimizeResult prediction = session.predict(/*warm=*/false, progress);
  nlohmann::json seconds = session.preparation_seconds();
  seconds["predict"] = seconds_since(stage);
  const LayeredTissue& tissue = session.tissue();
  const std::span<const Vec3> x = session.positions();
  nlohmann::json report = session.preparation_report();
  const double residual_force_after = session.residual_force();

  // Outputs (mm).
  report_progress("writing", 0.9);
  stage = Clock::now();
  std::filesystem::create_directories(out_dir);
  const BoneSegments& segments = session.segments();
  std::vector<int> moved_segments;
  for (int s = 0; s < segments.count; ++s) {
    const RigidMove& m = session.moves()[static_cast<std::size_t>(s)];
    if (m.angle != 0.0 || m.translation != Vec3::Zero()) {
      moved_segments.push_back(s);
    }
  }
  PlanSummary summary;
  summary.points = tissue.point_count();
  summary.springs = tissue.springs.size();
  summary.prisms = tissue.prisms.size();
  summary.segments = segments.count;
  summary.moved_segments = static_cast<int>(moved_segments.size());
  summary.residual_force_before = report["residual_force_before"].get<double>();
  summary.residual_force_after = residual_force_after;
  summary.prediction = prediction;
  const std::vector<Vec3> skin_before = session.skin_before();
  const std::vector<Vec3> skin_after = session.skin_after();
  double mean_displacement = 0.0;
  for (std::size_t c = 0; c < skin_before.size(); ++c) {
    const double moved = (skin_after[c] - skin_before[c]).norm() / kMillimetre;
    summary.max_displacement = std::max(summary.max_displacement, moved);
    mean_displacement += moved / static_cast<double>(skin_before.size());
  }
  write_surface_mm(out_dir / "skin_before.vtp", skin_before, tissue.skin_triangles, {}, {});
  write_surface_mm(out_dir / "skin_after.vtp", skin_after, tissue.skin_triangles, skin_before, {});
  write_bone_mm(out_dir / "bone_before.vtp", session.bone(), segments, {});
  write_bone_mm(out_dir / "bone_after.vtp", session.bone(), segments, session.moves());
  write_tissue_vtu_mm(out_dir / "tissue.vtu", tissue, x);
  seconds["write"] = seconds_since(stage);
  summary.skin_triangles = tissue.skin_triangles;
  summary.skin_before = skin_before;
  summary.skin_after = skin_after;

  std::vector<double> gaps;
  for (const auto& [a, b] : session.cut_skin_springs()) {
    gaps.push_back(
        ((x[static_cast<std::size_t>(a)] - x[static_cast<std::size_t>(b)]).norm() -
         (tissue.rest[static_cast<std::size_t>(a)] - tissue.rest[static_cast<std::size_t>(b)])
             .norm()) /
        kMillimetre);
  }
  report["moved_segments"] = moved_segments;
  {
    nlohmann::json list = nlohmann::json::array();
    for (int s = 0; s < segments.count; ++s) {
      const auto index = static_cast<std::size_t>(s);
      list.push_back({{"segment", s},
                      {"triangles", segments.sizes[index]},
                      {"volume_mm3", segments.volumes[index] / std::pow(kMillimetre, 3)},
                      {"moved", std::find(moved_segments.begin(), moved_segments.end(), s) !=
                                    moved_segments.end()}});
    }
    report["segment_list"] = list;
  }
  report["residual_force_after"] = residual_force_after;
  report["iterations"] = prediction.iterations;
  report["evaluations"] = prediction.evaluations;
  if (plan.solver.method == Minimizer::kNewton) {
    report["newton"] = {{"factorizations", prediction.factorizations},
                        {"lagged_steps", prediction.lagged_steps},
                        {"convexified_steps", prediction.convexified_steps},
                        {"pattern_analyses", prediction.pattern_analyses},
                        {"indefinite_attempts", prediction.indefinite_attempts},
                        {"steps", newton_steps_report(prediction.newton_steps)},
                        {"seconds",
                         {{"assembly", prediction.assembly_seconds},
                          {"factorization", prediction.factorization_seconds},
                          {"solve", prediction.solve_seconds},
                          {"line_search", prediction.line_search_seconds}}}};
  }
  report["converged"] = prediction.converged;
  report["stopped"] = prediction.message;
  report["objective_monotone"] = prediction.monotone;
  report["gradient_tolerance"] = session.gradient_tolerance();
  report["max_displacement"] = summary.max_displacement;
  report["mean_displacement"] = mean_displacement;
  if (!gaps.empty()) {
    double mean_gap = 0.0;
    for (double g : gaps) {
      mean_gap += g / static_cast<double>(gaps.size());
    }
    report["gap"] = {{"max", *std::max_element(gaps.begin(), gaps.end())}, {"mean", mean_gap}};
  }
  summary.seconds = seconds_since(start);
  seconds["total"] = summary.seconds;
  report["seconds"] = seconds;
  summary.report = out_dir / "report.json";
  write_file_atomically(summary.report, report.dump(2) + "\n");
  report_progress("done", 1.0);
  return summary;
}

}  // namespace incise::planning
