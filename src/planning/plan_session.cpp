// A plan prepared once (surfaces, segments, balanced tissue) and predicted per set of moves.

#include "incise/planning/plan_session.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/meshing/tetrahedralize.hpp"
#include "incise/planning/decimate.hpp"
#include "incise/planning/equilibrium.hpp"
#include "incise/planning/newton.hpp"
#include "incise/planning/surface_error.hpp"
#include "incise/planning/tissue_energy.hpp"
#include "plan_surfaces.hpp"

namespace incise::planning {

// Not in the anonymous namespace: PlanSession::State holds two (g++ warns of a member whose
// type has internal linkage where the file is compiled as part of a unity build).
struct PreparedSurface {
  SurfaceMesh surface;
  std::size_t triangles_full = 0;
  double hausdorff_to_input = 0.0;    ///< m: the largest (sampled with the mesher)
  double hausdorff_from_input = 0.0;  ///< m
  nlohmann::json report;              ///< how the surface was made and what it is worth
};

namespace {

/// Samples each way when a remeshed surface is measured against its input (as for a CT).
constexpr std::size_t kRemeshDistanceSamples = 100000;

SurfaceMesh scaled(SurfaceMesh surface, double factor) {
  for (Vec3& p : surface.points) {
    p *= factor;
  }
  return surface;
}

/// The surface as the plan asks (m): its largest component, within the decimation bound when
/// the plan gives one.
PreparedSurface prepare(const SurfaceMesh& input, const PlanDescription& plan) {
  PreparedSurface prepared;
  if (!plan.decimation_max_error) {
    prepared.surface = largest_component(input);
    prepared.triangles_full = prepared.surface.triangles.size();
    return prepared;
  }
  const double bound = *plan.decimation_max_error;  // m
  if (plan.decimation_method == DecimationMethod::kEnvelope) {
    DecimationResult decimated = decimate_surface(input, bound);
    prepared.triangles_full = decimated.triangles_before;
    prepared.surface = std::move(decimated.surface);
    prepared.hausdorff_to_input = decimated.hausdorff_to_input;
    prepared.hausdorff_from_input = decimated.hausdorff_from_input;
    prepared.report = {
        {"method", "envelope"},
        {"bound_means",
         "every point of the decimated surface lies within the bound of the input (CGAL's "
         "polyhedral envelope filter)"},
        {"measured", "CGAL's bounded-error Hausdorff distance, to a hundredth of the bound"}};
    return prepared;
  }
  // In millimetres, as the CT's isosurfaces are meshed.
  RemeshOptions options;
  options.max_error = bound / kMillimetre;
  const double layer =
      plan.tissue.max_thickness / static_cast<double>(std::max(plan.tissue.layers, 1));
  options.facet_size = std::max(
      (plan.decimation_facet_size > 0.0 ? plan.decimation_facet_size : layer) / kMillimetre,
      4.0 * options.max_error);
  options.seed = plan.isosurface.seed;
  const SurfaceMesh input_mm = scaled(input, 1.0 / kMillimetre);
  RemeshResult remeshed = remesh_within_bound(input_mm, options);
  const SurfaceDistance distance = measure_surface_distance(
      remeshed.surface, largest_component(input_mm), kRemeshDistanceSamples, options.seed);
  prepared.triangles_full = remeshed.triangles_before;
  prepared.surface = scaled(remeshed.surface, kMillimetre);
  prepared.hausdorff_to_input = distance.model_to_reference.max * kMillimetre;
  prepared.hausdorff_from_input = distance.reference_to_model.max * kMillimetre;
  prepared.report = {
      {"method", "mesher"},
      {"bound_means",
       "the mesher's facet distance: each triangle's circumcentre lies within the bound of the "
       "input (along the triangle's dual Voronoi edge); the whole surface is measured both ways"},
      {"facet_size", options.facet_size},
      {"level_set_grid", remeshed.grid},
      {"holes_filled", remeshed.holes_filled},
      {"triangles_over_holes_left_out", remeshed.triangles_over_holes},
      {"pieces_left_out_triangles", remeshed.pieces_left_out_triangles},
      {"p99",
       {{"decimated_to_input", distance.model_to_reference.p99},
        {"input_to_decimated", distance.reference_to_model.p99}}},
      {"measured",
       fmt::format("{} samples each way, uniform by area: with 99 % confidence at most {:.4f} % "
                   "of each surface lies beyond its max",
                   kRemeshDistanceSamples, 100.0 * distance.beyond_max_fraction)}};
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

bool is_identity(const RigidMove& move) {
  return move.angle == 0.0 && move.translation == Vec3::Zero();
}

}  // namespace

struct PlanSession::State {
  PlanDescription plan;
  PreparedSurface skin;
  PreparedSurface bone;
  BoneSegments segments;
  SegmentCuts cuts;              ///< where the segments were cut apart, for contact checks
  std::vector<RigidMove> moves;  ///< one per segment
  LayeredTissue tissue;
  EquilibriumReport balance;
  std::vector<std::pair<int, int>> cut_skin_springs;
  std::vector<Vec3> x;  ///< the last prediction (the scanned state before the first)
  MinimizeResult prediction;
  NewtonWorkspace newton;       ///< the Hessian's pattern and last factor, kept between predictions
  double largest_weight = 0.0;  ///< N
  double residual_force = 0.0;  ///< N, after the last prediction
  nlohmann::json report;
  nlohmann::json seconds;
};

namespace {

/// The instrument that holds soft point i (a skin point within its radius; the first such),
/// else null.
const Instrument* held_by(const PlanDescription& plan, const LayeredTissue& tissue, std::size_t i) {
  if (tissue.layer_of(static_cast<int>(i)) != 0) {
    return nullptr;
  }
  for (const Instrument& instrument : plan.instruments) {
    if ((tissue.rest[i] - instrument.near).norm() <= instrument.radius) {
      return &instrument;
    }
  }
  return nullptr;
}

}  // namespace

/// Per point, whether a prediction moves it: the soft points that no instrument holds.
std::vector<char> PlanSession::free_points(const State& s) {
  const LayeredTissue& tissue = s.tissue;
  std::vector<char> free(tissue.point_count(), 0);
  for (std::size_t i = 0; i < free.size(); ++i) {
    free[i] = tissue.kind[i] == PointKind::kSoft && held_by(s.plan, tissue, i) == nullptr ? 1 : 0;
  }
  return free;
}

PlanSession::PlanSession(const PlanDescription& plan, const PlanProgress& progress)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.plan = plan;
  auto report_progress = [&](const std::string& stage, double fraction) {
    if (progress) {
      progress(stage, fraction);
    }
  };
  nlohmann::json& report = s.report;
  nlohmann::json& seconds = s.seconds;
  report["plan"] = plan.file.string();
  report["units"] = {{"length", "mm"},        {"displacement", "mm"}, {"force", "N"},
                     {"young_modulus", "Pa"}, {"density", "kg/m^3"},  {"mass", "kg"},
                     {"gravity", "m/s^2"},    {"time", "s"}};

  // Surfaces: meshed from the CT within the plan's bound, or read and decimated to it. The
  // bone comes first, so a move that will be refused is refused before the skin is prepared.
  auto stage = Clock::now();
  SurfaceMesh skin_input;
  if (!plan.image.empty()) {
    PlanSurfaces surfaces = surfaces_from_image(plan, progress);
    seconds["image"] = surfaces.seconds_image;
    seconds["isosurface"] = surfaces.seconds_isosurface;
    seconds["surface_check"] = surfaces.seconds_check;
    report["image"] = std::move(surfaces.report);
    report["decimation"] =
        "none: the mesher meets the bound itself (isosurface_criteria.facet_distance)";
    s.skin.surface = std::move(surfaces.skin);
    s.skin.triangles_full = s.skin.surface.triangles.size();
    s.bone.surface = std::move(surfaces.bone);
    s.bone.triangles_full = s.bone.surface.triangles.size();
  } else {
    report_progress("reading surfaces", 0.0);
    skin_input = in_metres(read_surface(plan.skin));
    report_progress("decimating the bone", 0.05);
    s.bone = prepare(in_metres(read_surface(plan.bone)), plan);
    seconds["bone_surface"] = seconds_since(stage);
  }

  // Bone segments and the plan's moves, checked before anything is built.
  report_progress("cutting bone", 0.2);
  stage = Clock::now();
  s.segments = segment_bone(s.bone.surface, plan.osteotomies, plan.min_segment_volume);
  s.moves.assign(static_cast<std::size_t>(s.segments.count), RigidMove{});
  std::vector<int> moved_segments;
  for (std::size_t m = 0; m < plan.moves.size(); ++m) {
    const RigidMove& move = plan.moves[m];
    const int segment = nearest_segment(s.bone.surface, s.segments, move.segment_near);
    if (std::find(moved_segments.begin(), moved_segments.end(), segment) != moved_segments.end()) {
      throw InputError(plan.file.string(), 0,
                       fmt::format("plan key 'moves[{}]': bone segment {} is already moved by an "
                                   "earlier move (one move per segment)",
                                   m, segment));
    }
    s.moves[static_cast<std::size_t>(segment)] = move;
    moved_segments.push_back(segment);
  }
  s.cuts = segment_cuts(s.bone.surface, s.segments, plan.osteotomies, plan.contact_tolerance);
  const std::vector<Interpenetration> overlaps =
      find_interpenetrations(s.bone.surface, s.segments, s.moves, s.cuts);
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
    s.skin = prepare(skin_input, plan);
  }
  report["skin_triangles_decimated"] = s.skin.surface.triangles.size();
  if (plan.skin_edge_length) {
    report_progress("remeshing the skin", 0.2);
    try {
      s.skin.surface = remesh_surface(s.skin.surface, *plan.skin_edge_length);
    } catch (const InputError& error) {
      throw InputError(plan.file.string(), 0,
                       std::string("plan key 'skin_edge_length': ") + error.what());
    }
  }
  seconds["skin_surface"] = seconds_since(stage);
  report["skin_triangles_full"] = s.skin.triangles_full;
  report["skin_triangles"] = s.skin.surface.triangles.size();
  report["skin_edge_length"] = plan.skin_edge_length ? *plan.skin_edge_length / kMillimetre : 0.0;
  report["bone_triangles_full"] = s.bone.triangles_full;
  report["bone_triangles"] = s.bone.surface.triangles.size();
  if (plan.image.empty()) {
    report["decimation_max_error"] =
        plan.decimation_max_error ? *plan.decimation_max_error / kMillimetre : 0.0;
    report["hausdorff_skin"] = {{"decimated_to_input", s.skin.hausdorff_to_input / kMillimetre},
                                {"input_to_decimated", s.skin.hausdorff_from_input / kMillimetre}};
    report["hausdorff_bone"] = {{"decimated_to_input", s.bone.hausdorff_to_input / kMillimetre},
                                {"input_to_decimated", s.bone.hausdorff_from_input / kMillimetre}};
    if (plan.decimation_max_error) {
      report["decimation"] = {{"skin", s.skin.report}, {"bone", s.bone.report}};
    }
  }
  report["segments"] = s.segments.count;
  report["segment_triangles"] = s.segments.sizes;
  report["merged_fragments"] = s.segments.merged_fragments;
  report["small_isolated_segments"] = s.segments.small_isolated;
  report["min_segment_volume_mm3"] = plan.min_segment_volume / std::pow(kMillimetre, 3);
  report["contact_tolerance"] = plan.contact_tolerance / kMillimetre;

  // The layered tissue.
  report_progress("building the layered tissue", 0.3);
  stage = Clock::now();
  s.tissue = build_layered_tissue(s.skin.surface, s.bone.surface, plan.tissue);
  LayeredTissue& tissue = s.tissue;
  seconds["build"] = seconds_since(stage);

  // Equilibrium of the scanned state under gravity and skin pre-strain.
  report_progress("balancing the scanned state", 0.4);
  stage = Clock::now();
  if (plan.equilibrium) {
    // Through the prediction's factorisation: its Newton steps factorise the same pattern
    // (unless soft tissue is cut below) and need no analysis of their own.
    s.balance = initialise_equilibrium(tissue, plan.gravity, kEquilibriumTolerance,
                                       kEquilibriumIterations, &s.newton.lend_factorization());
  } else {
    const TissueEnergy unbalanced(tissue, plan.gravity);
    std::vector<Vec3> f(tissue.point_count());
    unbalanced.forces(tissue.rest, f);
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (tissue.kind[i] == PointKind::kSoft) {
        s.balance.residual_before = std::max(s.balance.residual_before, f[i].norm());
      }
    }
    s.balance.residual_after = s.balance.residual_before;
  }
  seconds["equilibrium"] = seconds_since(stage);

  // Soft-tissue cuts: springs and prisms across a disc go; the skin's pre-strain opens the gap.
  std::size_t cut_springs = 0;
  std::size_t cut_prisms = 0;
  if (!plan.cuts.empty()) {
    auto across = [&](int a, int b) {
      return std::any_of(plan.cuts.begin(), plan.cuts.end(), [&](const CutPlane& cut) {
        return crosses(cut, tissue.rest[static_cast<std::size_t>(a)],
                       tissue.rest[static_cast<std::size_t>(b)]);
      });
    };
    std::erase_if(tissue.springs, [&](const Spring& spring) {
      if (!across(spring.a, spring.b)) {
        return false;
      }
      ++cut_springs;
      if (spring.set == SpringSet::kLayer && spring.layer == 0) {
        s.cut_skin_springs.emplace_back(spring.a, spring.b);
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
  report["cut_springs"] = cut_springs;
  report["cut_prisms"] = cut_prisms;

  for (double m : tissue.mass) {
    s.largest_weight = std::max(s.largest_weight, m * plan.gravity.norm());
  }
  if (!(s.largest_weight > 0.0)) {
    s.largest_weight = 1e-6;  // N: no gravity; the scale of a small point's weight at 1 g
  }
  s.x = tissue.rest;

  report["layers"] = tissue.layers;
  report["points"] = tissue.point_count();
  report["soft_points"] = tissue.count(PointKind::kSoft);
  report["bone_points"] = tissue.count(PointKind::kBone);
  report["boundary_points"] = tissue.count(PointKind::kBoundary);
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
  double mass = 0.0;
  for (double m : tissue.mass) {
    mass += m;
  }
  report["mass"] = mass;
  report["equilibrium"] = plan.equilibrium;
  report["residual_force_before"] = s.balance.residual_before;
  report["residual_force_after_equilibrium"] = s.balance.residual_after;
  report["equilibrium_iterations"] = s.balance.iterations;
  if (tissue.elasticity == TissueElasticity::kContinuum) {
    report["largest_rest_shift"] = s.balance.largest_rest_shift / kMillimetre;
  } else {
    report["largest_rest_length_change"] = s.balance.largest_relative_change;
  }
  report["load_on_bone_and_boundary"] = {s.balance.load_on_fixed_points.x(),
                                         s.balance.load_on_fixed_points.y(),
                                         s.balance.load_on_fixed_points.z()};
  report["method"] = plan.method == PredictionMethod::kEnergy ? "energy" : "force";
  report["solver"] = to_string(plan.solver.method);
}

PlanSession::~PlanSession() = default;

const PlanDescription& PlanSession::plan() const {
  return state_->plan;
}
const SurfaceMesh& PlanSession::bone() const {
  return state_->bone.surface;
}
const BoneSegments& PlanSession::segments() const {
  return state_->segments;
}
const LayeredTissue& PlanSession::tissue() const {
  return state_->tissue;
}
std::span<const RigidMove> PlanSession::moves() const {
  return state_->moves;
}
const MinimizeResult& PlanSession::last_prediction() const {
  return state_->prediction;
}
double PlanSession::residual_force() const {
  return state_->residual_force;
}
std::span<const Vec3> PlanSession::positions() const {
  return state_->x;
}
std::span<const Triangle> PlanSession::skin_triangles() const {
  return state_->tissue.skin_triangles;
}
const nlohmann::json& PlanSession::preparation_report() const {
  return state_->report;
}
const nlohmann::json& PlanSession::preparation_seconds() const {
  return state_->seconds;
}

nlohmann::json newton_steps_report(const std::vector<NewtonStep>& steps) {
  nlohmann::json list = nlohmann::json::array();
  for (const NewtonStep& step : steps) {
    list.push_back({{"lagged_iterations", step.lagged_iterations},
                    {"lagged_budget", step.lagged_budget},
                    {"lagged", step.lagged},
                    {"convexified", step.convexified},
                    {"factorized", step.factorized},
                    {"step_length", step.step_length},
                    {"gradient", step.gradient}});
  }
  return list;
}

std::span<const std::pair<int, int>> PlanSession::cut_skin_springs() const {
  return state_->cut_skin_springs;
}

int PlanSession::segment_near(const Vec3& point) const {
  return nearest_segment(state_->bone.surface, state_->segments, point);
}

Vec3 PlanSession::segment_centre(int segment) const {
  const SurfaceMesh& bone = state_->bone.surface;
  Vec3 sum = Vec3::Zero();
  int corners = 0;
  for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
    if (state_->segments.triangle_segment[t] == segment) {
      for (const VertexId v : bone.triangles[t]) {
        sum += bone.points[static_cast<std::size_t>(v)];
        ++corners;
      }
    }
  }
  return sum / static_cast<double>(std::max(corners, 1));
}

std::vector<Interpenetration> PlanSession::try_move(int segment, const RigidMove& move) {
  State& s = *state_;
  if (segment < 0 || segment >= s.segments.count) {
    throw InputError(
        fmt::format("no bone segment {} (the bone has {})", segment, s.segments.count));
  }
  std::vector<RigidMove> trial = s.moves;
  trial[static_cast<std::size_t>(segment)] = move;
  std::vector<Interpenetration> overlaps =
      find_interpenetrations(s.bone.surface, s.segments, trial, s.cuts);
  if (overlaps.empty()) {
    s.moves = std::move(trial);
  }
  return overlaps;
}

double PlanSession::gradient_tolerance() const {
  const State& s = *state_;
  if (s.plan.method == PredictionMethod::kEnergy) {
    return s.plan.relative_tolerance * s.largest_weight;
  }
  // The force objective's gradient has units of N^2/m; its scale: stiffness times force.
  const TissueEnergy energy(s.tissue, s.plan.gravity);
  return s.plan.relative_tolerance * s.largest_weight * std::max(energy.mean_stiffness(), 1e-12);
}

const MinimizeResult& PlanSession::predict(bool warm, const PlanProgress& progress) {
  State& s = *state_;
  const LayeredTissue& tissue = s.tissue;
  // Where the fixed points go: bone points with their segment, boundary points stay,
  // instrument points are carried. Free points start where the last prediction left them.
  std::vector<Vec3> x = warm ? s.x : tissue.rest;
  const std::vector<char> free = free_points(s);
  std::size_t held = 0;
  bool bone_moved = false;  // from the scanned state
  for (std::size_t i = 0; i < x.size(); ++i) {
    const int column = tissue.column_of(static_cast<int>(i));
    if (tissue.kind[i] == PointKind::kBone) {
      const int triangle = tissue.column_bone_triangle[static_cast<std::size_t>(column)];
      const int segment = s.segments.triangle_segment[static_cast<std::size_t>(triangle)];
      x[i] = s.moves[static_cast<std::size_t>(segment)].apply(tissue.rest[i]);
      bone_moved = bone_moved || x[i] != tissue.rest[i];
    } else if (tissue.kind[i] == PointKind::kSoft && free[i] == 0) {
      x[i] = tissue.rest[i] + held_by(s.plan, tissue, i)->translation;
      ++held;
    }
  }
  s.report["instrument_points"] = held;
  {
    // The columns follow their bone ends' step (from the last prediction, or from the scan),
    // in proportion to depth (the skin's point not at all, the one beside the bone all the
    // way): a guess Newton starts near to, where the bone's jump alone would strain the tissue
    // beside it most (from the scan, the 59k-point phantom's 5 mm advancement: 8 -> 7 steps).
    const std::vector<Vec3>& from = warm ? s.x : tissue.rest;
    for (int c = 0; c < tissue.columns; ++c) {
      const auto end = static_cast<std::size_t>(tissue.point(c, tissue.layers));
      if (tissue.kind[end] != PointKind::kBone) {
        continue;
      }
      const Vec3 step = x[end] - from[end];
      for (int k = 1; k < tissue.layers; ++k) {
        const auto p = static_cast<std::size_t>(tissue.point(c, k));
        if (free[p] != 0) {
          x[p] += (static_cast<double>(k) / tissue.layers) * step;
        }
      }
    }
  }

  const TissueEnergy energy(tissue, s.plan.gravity);
  MinimizeOptions options = s.plan.solver;
  options.gradient_tolerance = gradient_tolerance();
  Objective objective;
  if (s.plan.method == PredictionMethod::kEnergy) {
    objective = [&](std::span<const Vec3> at, std::span<Vec3> gradient) {
      return energy.energy(at, gradient);
    };
  } else {
    objective = [&](std::span<const Vec3> at, std::span<Vec3> gradient) {
      return energy.force_objective(at, free, gradient);
    };
  }
  const int report_every = options.method == Minimizer::kNewton ? 1 : 25;
  const MinimizeProgress minimize_progress = [&](int iteration, double gradient) {
    if (progress && iteration % report_every == 0) {
      const double ratio = gradient > 0.0 ? options.gradient_tolerance / gradient : 1.0;
      // Progress by orders of magnitude of the gradient still to go.
      const double done = std::clamp(1.0 + std::log10(std::min(ratio, 1.0)) / 8.0, 0.0, 1.0);
      progress(fmt::format("predicting (iteration {})", iteration), 0.5 + 0.4 * done);
    }
  };
  if (!warm) {
    s.newton.forget_factor();  // what incise plan computes, to the last bit
    if (bone_moved) {
      // Bone moved from the scanned state into the tissue beside it: the exact Hessian there
      // is indefinite (so on every example plan and phantom), and trying it first would cost
      // an assembly and a failed factorisation before the same convex step.
      s.newton.start_convex();
    }
  } else if (options.method == Minimizer::kNewton && !s.newton.has_factor()) {
    // The first warm prediction (the last one took no step): the Hessian factorised where the
    // last one ended, a minimum, so that this and the next nudges' Newton steps start with a
    // factor in hand and need none of their own while the moves stay small.
    s.newton.factorize_at(energy, s.x, free);
  }
  MinimizeResult result =
      options.method == Minimizer::kNewton
          ? minimize_newton(energy, x, free, options, minimize_progress, &s.newton)
          : minimize(objective, x, free, options, minimize_progress);
  for (const Vec3& p : x) {
    if (!p.allFinite()) {
      throw InputError(s.plan.file.string(), 0,
                       "the prediction diverged (non-finite positions); nothing was written");
    }
  }
  s.residual_force = energy.largest_free_force(x, free);
  s.x = std::move(x);
  s.prediction = result;
  return s.prediction;
}

void PlanSession::prepare_next_nudge() {
  State& s = *state_;
  if (s.plan.solver.method != Minimizer::kNewton) {
    return;
  }
  const TissueEnergy energy(s.tissue, s.plan.gravity);
  s.newton.factorize_at(energy, s.x, free_points(s));
}

std::vector<Vec3> PlanSession::skin_before() const {
  const LayeredTissue& tissue = state_->tissue;
  std::vector<Vec3> skin(static_cast<std::size_t>(tissue.columns));
  for (int c = 0; c < tissue.columns; ++c) {
    skin[static_cast<std::size_t>(c)] = tissue.rest[static_cast<std::size_t>(tissue.point(c, 0))];
  }
  return skin;
}

std::vector<Vec3> PlanSession::skin_after() const {
  const LayeredTissue& tissue = state_->tissue;
  std::vector<Vec3> skin(static_cast<std::size_t>(tissue.columns));
  for (int c = 0; c < tissue.columns; ++c) {
    skin[static_cast<std::size_t>(c)] = state_->x[static_cast<std::size_t>(tissue.point(c, 0))];
  }
  return skin;
}

nlohmann::json PlanSession::plan_with_moves(const nlohmann::json& original) const {
  const State& s = *state_;
  nlohmann::json plan = original;
  nlohmann::json moves = nlohmann::json::array();
  for (int segment = 0; segment < s.segments.count; ++segment) {
    const RigidMove& move = s.moves[static_cast<std::size_t>(segment)];
    if (is_identity(move)) {
      continue;
    }
    // A point of the segment that is nearest to it alone: the centroid of its largest triangle.
    std::size_t best = 0;
    double best_area = -1.0;
    for (std::size_t t = 0; t < s.bone.surface.triangles.size(); ++t) {
      if (s.segments.triangle_segment[t] != segment) {
        continue;
      }
      const Triangle& tri = s.bone.surface.triangles[t];
      const Vec3& a = s.bone.surface.points[static_cast<std::size_t>(tri[0])];
      const double area = (s.bone.surface.points[static_cast<std::size_t>(tri[1])] - a)
                              .cross(s.bone.surface.points[static_cast<std::size_t>(tri[2])] - a)
                              .norm();
      if (area > best_area) {
        best_area = area;
        best = t;
      }
    }
    const Triangle& tri = s.bone.surface.triangles[best];
    const Vec3 near = (s.bone.surface.points[static_cast<std::size_t>(tri[0])] +
                       s.bone.surface.points[static_cast<std::size_t>(tri[1])] +
                       s.bone.surface.points[static_cast<std::size_t>(tri[2])]) /
                      (3.0 * kMillimetre);
    const Vec3 translate = move.translation / kMillimetre;
    nlohmann::json item = {{"segment_near", {near.x(), near.y(), near.z()}},
                           {"translate", {translate.x(), translate.y(), translate.z()}}};
    if (move.angle != 0.0) {
      const Vec3 axis = move.axis.normalized();
      const Vec3 centre = move.center / kMillimetre;
      item["rotate"] = {{"axis", {axis.x(), axis.y(), axis.z()}},
                        {"angle_deg", move.angle * 180.0 / 3.14159265358979323846},
                        {"center", {centre.x(), centre.y(), centre.z()}}};
    }
    moves.push_back(item);
  }
  plan["moves"] = moves;
  return plan;
}

}  // namespace incise::planning
