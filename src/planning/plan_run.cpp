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
#include "incise/planning/prism.hpp"
#include "incise/planning/tissue_energy.hpp"
#include "plan_surfaces.hpp"
#include "tissue_output.hpp"

namespace incise::planning {

namespace {

constexpr double kMillimetre = 1e-3;  // m

struct PreparedSurface {
  SurfaceMesh surface;
  std::size_t triangles_full = 0;
  double hausdorff_to_input = 0.0;
  double hausdorff_from_input = 0.0;
};

PreparedSurface prepare(const SurfaceMesh& input, const std::optional<double>& max_error) {
  PreparedSurface prepared;
  if (max_error) {
    DecimationResult decimated = decimate_surface(input, *max_error);
    prepared.triangles_full = decimated.triangles_before;
    prepared.surface = std::move(decimated.surface);
    prepared.hausdorff_to_input = decimated.hausdorff_to_input;
    prepared.hausdorff_from_input = decimated.hausdorff_from_input;
  } else {
    prepared.surface = largest_component(input);
    prepared.triangles_full = prepared.surface.triangles.size();
  }
  return prepared;
}

/// Whether the segment from p to q crosses the disc.
bool crosses(const CutPlane& plane, const Vec3& p, const Vec3& q) {
  const double sp = (p - plane.point).dot(plane.normal);
  const double sq = (q - plane.point).dot(plane.normal);
  if ((sp >= 0.0) == (sq >= 0.0)) {
    return false;
  }
  const Vec3 hit = p + (sp / (sp - sq)) * (q - p);
  return (hit - plane.point).norm() <= plane.radius;
}

}  // namespace

PlanSummary run_plan(const PlanDescription& plan, const std::filesystem::path& out_dir,
                     const PlanProgress& progress) {
  const auto start = Clock::now();
  auto report_progress = [&](const std::string& stage, double fraction) {
    if (progress) {
      progress(stage, fraction);
    }
  };
  nlohmann::json report;
  nlohmann::json seconds;
  report["plan"] = plan.file.string();
  report["units"] = {{"length", "mm"},        {"displacement", "mm"}, {"force", "N"},
                     {"young_modulus", "Pa"}, {"density", "kg/m^3"},  {"mass", "kg"},
                     {"gravity", "m/s^2"},    {"time", "s"}};

  // Surfaces: meshed from the CT within the plan's bound, or read and decimated to it. The
  // bone comes first, so a move that will be refused is refused before the skin is prepared.
  auto stage = Clock::now();
  PreparedSurface skin;
  PreparedSurface bone;
  SurfaceMesh skin_input;
  if (!plan.image.empty()) {
    PlanSurfaces surfaces = surfaces_from_image(plan, progress);
    seconds["image"] = surfaces.seconds_image;
    seconds["isosurface"] = surfaces.seconds_isosurface;
    seconds["surface_check"] = surfaces.seconds_check;
    report["image"] = std::move(surfaces.report);
    report["decimation"] =
        "none: the mesher meets the bound itself (isosurface_criteria.facet_distance)";
    skin.surface = std::move(surfaces.skin);
    skin.triangles_full = skin.surface.triangles.size();
    bone.surface = std::move(surfaces.bone);
    bone.triangles_full = bone.surface.triangles.size();
  } else {
    report_progress("reading surfaces", 0.0);
    skin_input = in_metres(read_surface(plan.skin));
    report_progress("decimating the bone", 0.05);
    bone = prepare(in_metres(read_surface(plan.bone)), plan.decimation_max_error);
    seconds["bone_surface"] = seconds_since(stage);
  }

  // Bone segments and their moves, checked before anything is built.
  report_progress("cutting bone", 0.2);
  stage = Clock::now();
  const BoneSegments segments =
      segment_bone(bone.surface, plan.osteotomies, plan.min_segment_volume);
  std::vector<RigidMove> segment_moves(static_cast<std::size_t>(segments.count));
  std::vector<int> moved_segments;
  for (std::size_t m = 0; m < plan.moves.size(); ++m) {
    const RigidMove& move = plan.moves[m];
    const int segment = nearest_segment(bone.surface, segments, move.segment_near);
    if (std::find(moved_segments.begin(), moved_segments.end(), segment) != moved_segments.end()) {
      throw InputError(plan.file.string(), 0,
                       fmt::format("plan key 'moves[{}]': bone segment {} is already moved by an "
                                   "earlier move (one move per segment)",
                                   m, segment));
    }
    segment_moves[static_cast<std::size_t>(segment)] = move;
    moved_segments.push_back(segment);
  }
  const std::vector<Interpenetration> overlaps = find_interpenetrations(
      bone.surface, segments, segment_moves, plan.osteotomies, plan.contact_tolerance);
  if (!overlaps.empty()) {
    std::string list;
    for (const Interpenetration& o : overlaps) {
      list += fmt::format(
          "{}segments {} and {} ({} crossing triangle pairs away from their cut, {:.2f} mm "
          "beyond it)",
          list.empty() ? "" : "; ", o.first, o.second, o.crossing_triangle_pairs,
          o.depth / kMillimetre);
    }
    throw InputError(plan.file.string(), 0,
                     fmt::format("plan key 'moves': the moved bone segments interpenetrate "
                                 "(contact_tolerance {} mm): {}",
                                 plan.contact_tolerance / kMillimetre, list));
  }
  seconds["bone"] = seconds_since(stage);

  stage = Clock::now();
  if (plan.image.empty()) {
    report_progress("decimating the skin", 0.15);
    skin = prepare(skin_input, plan.decimation_max_error);
  }
  report["skin_triangles_decimated"] = skin.surface.triangles.size();
  if (plan.skin_edge_length) {
    report_progress("remeshing the skin", 0.2);
    try {
      skin.surface = remesh_surface(skin.surface, *plan.skin_edge_length);
    } catch (const InputError& error) {
      throw InputError(plan.file.string(), 0,
                       std::string("plan key 'skin_edge_length': ") + error.what());
    }
  }
  seconds["skin_surface"] = seconds_since(stage);
  report["skin_triangles_full"] = skin.triangles_full;
  report["skin_triangles"] = skin.surface.triangles.size();
  report["skin_edge_length"] = plan.skin_edge_length ? *plan.skin_edge_length / kMillimetre : 0.0;
  report["bone_triangles_full"] = bone.triangles_full;
  report["bone_triangles"] = bone.surface.triangles.size();
  if (plan.image.empty()) {
    report["decimation_max_error"] =
        plan.decimation_max_error ? *plan.decimation_max_error / kMillimetre : 0.0;
    report["hausdorff_skin"] = {{"decimated_to_input", skin.hausdorff_to_input / kMillimetre},
                                {"input_to_decimated", skin.hausdorff_from_input / kMillimetre}};
    report["hausdorff_bone"] = {{"decimated_to_input", bone.hausdorff_to_input / kMillimetre},
                                {"input_to_decimated", bone.hausdorff_from_input / kMillimetre}};
  }
  report["segments"] = segments.count;
  report["segment_triangles"] = segments.sizes;
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
    report["merged_fragments"] = segments.merged_fragments;
    report["small_isolated_segments"] = segments.small_isolated;
    report["min_segment_volume_mm3"] = plan.min_segment_volume / std::pow(kMillimetre, 3);
    report["contact_tolerance"] = plan.contact_tolerance / kMillimetre;
  }

  // The layered tissue.
  report_progress("building the layered tissue", 0.3);
  stage = Clock::now();
  LayeredTissue tissue = build_layered_tissue(skin.surface, bone.surface, plan.tissue);
  seconds["build"] = seconds_since(stage);

  // Equilibrium of the scanned state under gravity and skin pre-strain.
  report_progress("balancing the scanned state", 0.4);
  stage = Clock::now();
  EquilibriumReport balance;
  if (plan.equilibrium) {
    balance = initialise_equilibrium(tissue, plan.gravity);
  } else {
    const TissueEnergy unbalanced(tissue, plan.gravity);
    std::vector<Vec3> f(tissue.point_count());
    unbalanced.forces(tissue.rest, f);
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (tissue.kind[i] == PointKind::kSoft) {
        balance.residual_before = std::max(balance.residual_before, f[i].norm());
      }
    }
    balance.residual_after = balance.residual_before;
  }
  seconds["equilibrium"] = seconds_since(stage);

  // Soft-tissue cuts: springs and prisms across a disc go; the skin's pre-strain opens the gap.
  std::vector<std::pair<int, int>> cut_skin_springs;
  std::size_t cut_springs = 0;
  std::size_t cut_prisms = 0;
  if (!plan.cuts.empty()) {
    auto across = [&](int a, int b) {
      return std::any_of(plan.cuts.begin(), plan.cuts.end(), [&](const CutPlane& cut) {
        return crosses(cut, tissue.rest[static_cast<std::size_t>(a)],
                       tissue.rest[static_cast<std::size_t>(b)]);
      });
    };
    std::erase_if(tissue.springs, [&](const Spring& s) {
      if (!across(s.a, s.b)) {
        return false;
      }
      ++cut_springs;
      if (s.set == SpringSet::kLayer && s.layer == 0) {
        cut_skin_springs.emplace_back(s.a, s.b);
      }
      return true;
    });
    std::erase_if(tissue.prisms, [&](const Prism& prism) {
      for (int i = 0; i < 6; ++i) {
        for (int j = i + 1; j < 6; ++j) {
          if (across(prism.points[static_cast<std::size_t>(i)],
                     prism.points[static_cast<std::size_t>(j)])) {
            ++cut_prisms;
            return true;
          }
        }
      }
      return false;
    });
  }

  // Where the fixed points go: bone points with their segment, boundary points stay,
  // instrument points are carried.
  std::vector<Vec3> x = tissue.rest;
  std::vector<char> free(tissue.point_count(), 0);
  std::size_t held = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const int column = tissue.column_of(static_cast<int>(i));
    if (tissue.kind[i] == PointKind::kBone) {
      const int triangle = tissue.column_bone_triangle[static_cast<std::size_t>(column)];
      const int segment = segments.triangle_segment[static_cast<std::size_t>(triangle)];
      x[i] = segment_moves[static_cast<std::size_t>(segment)].apply(tissue.rest[i]);
    } else if (tissue.kind[i] == PointKind::kSoft) {
      free[i] = 1;
      if (tissue.layer_of(static_cast<int>(i)) == 0) {
        for (const Instrument& instrument : plan.instruments) {
          if ((tissue.rest[i] - instrument.near).norm() <= instrument.radius) {
            x[i] = tissue.rest[i] + instrument.translation;
            free[i] = 0;
            ++held;
            break;
          }
        }
      }
    }
  }

  // Prediction.
  report_progress("predicting the soft tissue", 0.5);
  stage = Clock::now();
  const TissueEnergy energy(tissue, plan.gravity);
  double largest_weight = 0.0;
  for (double m : tissue.mass) {
    largest_weight = std::max(largest_weight, m * plan.gravity.norm());
  }
  if (!(largest_weight > 0.0)) {
    largest_weight = 1e-6;  // N: no gravity; the scale of a small point's weight at 1 g
  }
  MinimizeOptions options = plan.solver;
  Objective objective;
  if (plan.method == PredictionMethod::kEnergy) {
    options.gradient_tolerance = plan.relative_tolerance * largest_weight;
    objective = [&](std::span<const Vec3> at, std::span<Vec3> gradient) {
      return energy.energy(at, gradient);
    };
  } else {
    // The force objective's gradient has units of N^2/m; its scale: stiffness times force.
    options.gradient_tolerance =
        plan.relative_tolerance * largest_weight * std::max(energy.mean_stiffness(), 1e-12);
    objective = [&](std::span<const Vec3> at, std::span<Vec3> gradient) {
      return energy.force_objective(at, free, gradient);
    };
  }
  const int report_every = options.method == Minimizer::kNewton ? 1 : 25;
  const MinimizeProgress minimize_progress = [&](int iteration, double gradient) {
    if (iteration % report_every == 0) {
      const double ratio = gradient > 0.0 ? options.gradient_tolerance / gradient : 1.0;
      // Progress by orders of magnitude of the gradient still to go.
      const double done = std::clamp(1.0 + std::log10(std::min(ratio, 1.0)) / 8.0, 0.0, 1.0);
      report_progress(fmt::format("predicting (iteration {})", iteration), 0.5 + 0.4 * done);
    }
  };
  const MinimizeResult prediction =
      options.method == Minimizer::kNewton
          ? minimize_newton(energy, x, free, options, minimize_progress)
          : minimize(objective, x, free, options, minimize_progress);
  seconds["predict"] = seconds_since(stage);
  for (const Vec3& p : x) {
    if (!p.allFinite()) {
      throw InputError(plan.file.string(), 0,
                       "the prediction diverged (non-finite positions); nothing was written");
    }
  }
  const double residual_force_after = energy.largest_free_force(x, free);

  // Outputs (mm).
  report_progress("writing", 0.9);
  stage = Clock::now();
  std::filesystem::create_directories(out_dir);
  PlanSummary summary;
  summary.points = tissue.point_count();
  summary.springs = tissue.springs.size();
  summary.prisms = tissue.prisms.size();
  summary.segments = segments.count;
  summary.moved_segments = static_cast<int>(moved_segments.size());
  summary.residual_force_before = balance.residual_before;
  summary.residual_force_after = residual_force_after;
  summary.prediction = prediction;
  std::vector<Vec3> skin_before(static_cast<std::size_t>(tissue.columns));
  std::vector<Vec3> skin_after(skin_before.size());
  double mean_displacement = 0.0;
  for (int c = 0; c < tissue.columns; ++c) {
    const auto p = static_cast<std::size_t>(tissue.point(c, 0));
    skin_before[static_cast<std::size_t>(c)] = tissue.rest[p];
    skin_after[static_cast<std::size_t>(c)] = x[p];
    const double moved = (x[p] - tissue.rest[p]).norm() / kMillimetre;
    summary.max_displacement = std::max(summary.max_displacement, moved);
    mean_displacement += moved / tissue.columns;
  }
  write_surface_mm(out_dir / "skin_before.vtp", skin_before, tissue.skin_triangles, {}, {});
  write_surface_mm(out_dir / "skin_after.vtp", skin_after, tissue.skin_triangles, skin_before, {});
  write_bone_mm(out_dir / "bone_before.vtp", bone.surface, segments, {});
  write_bone_mm(out_dir / "bone_after.vtp", bone.surface, segments, segment_moves);
  write_tissue_vtu_mm(out_dir / "tissue.vtu", tissue, x);
  seconds["write"] = seconds_since(stage);
  summary.skin_triangles = tissue.skin_triangles;
  summary.skin_before = skin_before;
  summary.skin_after = skin_after;

  std::vector<double> gaps;
  for (const auto& [a, b] : cut_skin_springs) {
    gaps.push_back(
        ((x[static_cast<std::size_t>(a)] - x[static_cast<std::size_t>(b)]).norm() -
         (tissue.rest[static_cast<std::size_t>(a)] - tissue.rest[static_cast<std::size_t>(b)])
             .norm()) /
        kMillimetre);
  }
  report["layers"] = tissue.layers;
  report["points"] = tissue.point_count();
  report["soft_points"] = tissue.count(PointKind::kSoft);
  report["bone_points"] = tissue.count(PointKind::kBone);
  report["boundary_points"] = tissue.count(PointKind::kBoundary);
  report["instrument_points"] = held;
  report["skin_triangles_left_out"] = tissue.skin_triangles_dropped;
  report["folded_skin_triangles"] = tissue.folded_triangles;
  report["elasticity"] =
      tissue.elasticity == TissueElasticity::kContinuum ? "continuum" : "springs";
  report["springs"] = tissue.springs.size();
  report["prisms"] = tissue.prisms.size();
  if (tissue.elasticity == TissueElasticity::kContinuum) {
    std::size_t tetrahedra = 0;
    for (const Prism& prism : tissue.prisms) {
      for (const PrismTet& tet : prism.tets) {
        tetrahedra += tet.rest.volume > 0.0 ? 1 : 0;
      }
    }
    report["tetrahedra"] = tetrahedra;
    report["sliver_tetrahedra_left_empty"] = tissue.sliver_tets;
    report["skin_thickness"] = plan.tissue.skin_thickness / kMillimetre;
  }
  report["skin_prestrain"] = tissue.skin_prestrain;
  report["nonlinear"] = tissue.law.nonlinearity;
  report["volume_weight"] = tissue.volume_weight;
  report["mass"] = [&] {
    double sum = 0.0;
    for (double m : tissue.mass) {
      sum += m;
    }
    return sum;
  }();
  report["equilibrium"] = plan.equilibrium;
  report["residual_force_before"] = balance.residual_before;
  report["residual_force_after_equilibrium"] = balance.residual_after;
  report["equilibrium_iterations"] = balance.iterations;
  if (tissue.elasticity == TissueElasticity::kContinuum) {
    report["largest_rest_shift"] = balance.largest_rest_shift / kMillimetre;
  } else {
    report["largest_rest_length_change"] = balance.largest_relative_change;
  }
  report["load_on_bone_and_boundary"] = {balance.load_on_fixed_points.x(),
                                         balance.load_on_fixed_points.y(),
                                         balance.load_on_fixed_points.z()};
  report["residual_force_after"] = residual_force_after;
  report["method"] = plan.method == PredictionMethod::kEnergy ? "energy" : "force";
  report["solver"] = to_string(plan.solver.method);
  report["iterations"] = prediction.iterations;
  report["evaluations"] = prediction.evaluations;
  if (plan.solver.method == Minimizer::kNewton) {
    report["newton"] = {{"factorizations", prediction.factorizations},
                        {"lagged_steps", prediction.lagged_steps},
                        {"convexified_steps", prediction.convexified_steps}};
  }
  report["converged"] = prediction.converged;
  report["stopped"] = prediction.message;
  report["objective_monotone"] = prediction.monotone;
  report["gradient_tolerance"] = options.gradient_tolerance;
  report["max_displacement"] = summary.max_displacement;
  report["mean_displacement"] = mean_displacement;
  report["cut_springs"] = cut_springs;
  report["cut_prisms"] = cut_prisms;
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
