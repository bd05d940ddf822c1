#include "plan_surfaces.hpp"

#include <fmt/format.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "incise/core/error.hpp"
#include "incise/core/silenced_standard_output.hpp"
#include "incise/core/timing.hpp"
#include "incise/imaging/read_volume.hpp"
#include "incise/planning/surface_error.hpp"

namespace incise::planning {

namespace {

/// Samples each way when a surface is measured against the isosurface: the largest distance
/// then holds for all but ln(100)/n = 0.005 % of the surface with 99 % confidence.
constexpr std::size_t kDistanceSamples = 100000;

struct Kept {
  std::vector<char> keep;  ///< per triangle
  nlohmann::json report;
};

/// The skin: the body, the component that encloses the most (the scanner's table, closed
/// airways and whatever else crosses the skin's iso value are left out).
Kept keep_body(const SurfaceComponents& parts) {
  std::size_t best = 0;
  for (std::size_t c = 1; c < parts.components.size(); ++c) {
    if (parts.components[c].volume > parts.components[best].volume) {
      best = c;
    }
  }
  Kept kept;
  std::vector<char> keep_component(parts.components.size(), 0);
  keep_component[best] = 1;
  kept.keep = triangles_of(parts, keep_component);
  const auto left_out_triangles =
      static_cast<std::size_t>(std::count(kept.keep.begin(), kept.keep.end(), 0));
  kept.report = {{"kept", 1},
                 {"kept_volume_mm3", parts.components[best].volume},
                 {"left_out", parts.components.size() - 1},
                 {"left_out_triangles", left_out_triangles},
                 {"rule",
                  "the component enclosing the largest volume (the body); the others "
                  "(the scanner's table, closed airways, specks) are left out"}};
  return kept;
}

/// The bone: every component enclosing at least `least_volume` (mm^3); cavities (components
/// facing inwards, negative volume) and specks are left out.
Kept keep_bones(const SurfaceComponents& parts, double least_volume) {
  Kept kept;
  std::vector<char> keep_component(parts.components.size(), 0);
  std::size_t kept_count = 0;
  std::size_t cavities = 0;
  std::size_t specks = 0;
  nlohmann::json volumes = nlohmann::json::array();
  for (std::size_t c = 0; c < parts.components.size(); ++c) {
    const double volume = parts.components[c].volume;
    if (volume < 0.0) {
      ++cavities;
    } else if (volume < least_volume) {
      ++specks;
    } else {
      keep_component[c] = 1;
      ++kept_count;
      volumes.push_back(volume);
    }
  }
  kept.keep = triangles_of(parts, keep_component);
  const auto left_out_triangles =
      static_cast<std::size_t>(std::count(kept.keep.begin(), kept.keep.end(), 0));
  kept.report = {{"kept", kept_count},
                 {"kept_volumes_mm3", volumes},
                 {"left_out_cavities", cavities},
                 {"left_out_specks", specks},
                 {"left_out_triangles", left_out_triangles},
                 {"rule", fmt::format("components enclosing at least {} mm^3 (the plan's "
                                      "min_segment_volume); cavities inside bone and smaller "
                                      "specks are left out",
                                      least_volume)}};
  return kept;
}

/// Throws InputError naming the plan key when no component of an isosurface encloses more
/// than `least_volume` (mm^3): the iso value misses the anatomy (on a DICOM CT read in
/// Hounsfield units, a value meant for the stored numbers lies 1024 too high).
void refuse_without_a_kept_component(const PlanDescription& plan, const std::string& key,
                                     double iso, const SurfaceComponents& parts,
                                     double least_volume, double low, double high) {
  double largest = 0.0;
  for (const SurfaceComponent& part : parts.components) {
    largest = std::max(largest, part.volume);
  }
  if (largest > least_volume && largest > 0.0) {
    return;
  }
  throw InputError(fmt::format(
      "{}: plan key '{}' ({}): no part of the isosurface encloses {} (the largest of its {} "
      "parts encloses {:.3g} mm^3); the image's values range from {} to {}: is the iso value "
      "in the image's units (Hounsfield units for a DICOM CT, with its rescale applied)?",
      plan.file.string(), key, iso,
      least_volume > 0.0 ? fmt::format("at least {:.3g} mm^3 (min_segment_volume)", least_volume)
                         : std::string("a volume"),
      parts.components.size(), largest, low, high));
}

nlohmann::json distance_report(const IsosurfaceDistance& d, double bound) {
  auto side = [](const OneSidedDistance& s) {
    return nlohmann::json{{"max", s.max}, {"p99", s.p99}, {"mean", s.mean}, {"samples", s.samples}};
  };
  nlohmann::json to = side(d.model_to_isosurface);
  to["unresolved_samples"] = d.model_to_isosurface.unresolved;
  to["samples_at_scan_border"] = d.model_to_isosurface.at_scan_border;
  nlohmann::json from = side(d.isosurface_to_model);
  from["samples_on_surfaces_left_out"] = d.isosurface_to_model.left_out;
  from["samples_on_enclosed_cavities"] = d.isosurface_to_model.enclosed;
  from["samples_on_small_regions"] = d.isosurface_to_model.on_small_regions;
  from["samples_at_scan_border"] = d.isosurface_to_model.at_scan_border;
  return {{"bound", bound},
          {"bound_means",
           "the mesher's facet distance: each triangle's circumcentre lies within the bound of "
           "the isosurface (measured along the triangle's dual Voronoi edge); the whole surface "
           "is measured below, both ways"},
          {"model_to_isosurface", to},
          {"isosurface_to_model", from},
          {"isosurface_crossings", d.isosurface_crossings},
          {"confidence",
           fmt::format("sampled: with 99 % confidence at most {:.4f} % of each surface lies "
                       "beyond its max",
                       100.0 * d.beyond_max_fraction)},
          {"left_out_of_the_comparison",
           "samples within a voxel of the scan border (the surface is open where the tissue "
           "leaves the scanned region); the isosurface's points on the walls of enclosed "
           "regions (below the iso value and cut off from the scan's border: airways, sinuses, "
           "marrow), which the model's outer surface does not represent; those around regions "
           "above the iso value smaller than the model holds (specks of cancellous bone or "
           "noise: below min_segment_volume for the bone, facet_size cubed for the skin); and "
           "those nearest a component left out"}};
}

}  // namespace

SurfaceMesh in_metres(SurfaceMesh surface) {
  for (Vec3& p : surface.points) {
    p *= kMillimetre;
  }
  return surface;
}

imaging::IsosurfaceOptions isosurface_criteria(const PlanDescription& plan, const Vec3& spacing) {
  imaging::IsosurfaceOptions options = plan.isosurface;
  if (!(options.facet_size > 0.0)) {
    const double layer = plan.tissue.max_thickness / kMillimetre /
                         static_cast<double>(std::max(plan.tissue.layers, 1));
    options.facet_size = std::max(layer, 2.0 * spacing.maxCoeff());
  }
  if (!(options.facet_distance > 0.0)) {
    options.facet_distance = plan.decimation_max_error ? *plan.decimation_max_error / kMillimetre
                                                       : std::max(0.5, 0.5 * spacing.minCoeff());
  }
  return options;
}

PlanSurfaces surfaces_from_image(const PlanDescription& plan, const PlanProgress& progress) {
  auto report_progress = [&](const std::string& stage, double fraction) {
    if (progress) {
      progress(stage, fraction);
    }
  };
  PlanSurfaces result;
  auto stage = Clock::now();
  report_progress("reading the CT volume", 0.0);
  const imaging::VolumeImage image = imaging::read_volume(plan.image);
  result.seconds_image = seconds_since(stage);

  report_progress("meshing the skin and bone isosurfaces", 0.02);
  stage = Clock::now();
  const imaging::IsosurfaceOptions options = isosurface_criteria(plan, image.spacing);
  imaging::Isosurface skin;
  imaging::Isosurface bone;
  // One mesher per surface, side by side: each stays sequential, so results repeat exactly.
  // CGAL's seeding prints its progress to std::cout: it goes nowhere while the meshers run.
  {
    const SilencedStandardOutput quiet;
    tbb::parallel_invoke(
        [&] {
          skin = imaging::extract_isosurface(image, plan.skin_iso, options,
                                             plan.file.string() + ": plan key 'iso.skin'");
        },
        [&] {
          bone = imaging::extract_isosurface(image, plan.bone_iso, options,
                                             plan.file.string() + ": plan key 'iso.bone'");
        });
  }
  result.seconds_isosurface = seconds_since(stage);

  report_progress("checking the surfaces against the CT", 0.1);
  stage = Clock::now();
  const SurfaceComponents skin_parts = surface_components(skin.surface);
  const SurfaceComponents bone_parts = surface_components(bone.surface);
  const double least_bone = plan.min_segment_volume / std::pow(kMillimetre, 3);  // mm^3
  const auto [low, high] = imaging::value_range(image);
  refuse_without_a_kept_component(plan, "iso.skin", plan.skin_iso, skin_parts, 0.0, low, high);
  refuse_without_a_kept_component(plan, "iso.bone", plan.bone_iso, bone_parts, least_bone, low,
                                  high);
  const Kept skin_kept = keep_body(skin_parts);
  const Kept bone_kept = keep_bones(bone_parts, least_bone);
  const double smallest_meshed = std::pow(options.facet_size, 3);  // mm^3
  // Side by side: each measurement's region scans (enclosed regions, specks) run on one core,
  // so two of them fill both (the 512 phantom's check: 1.17 s -> 1.04 s, before the crossings'
  // scan was made one pass).
  IsosurfaceDistance skin_distance;
  IsosurfaceDistance bone_distance;
  tbb::parallel_invoke(
      [&] {
        skin_distance =
            measure_isosurface_distance(image, plan.skin_iso, skin.surface, skin_kept.keep,
                                        kDistanceSamples, options.seed, smallest_meshed);
      },
      [&] {
        bone_distance = measure_isosurface_distance(
            image, plan.bone_iso, bone.surface, bone_kept.keep, kDistanceSamples, options.seed + 1,
            std::max(least_bone, smallest_meshed));
      });
  result.skin = in_metres(select_triangles(skin.surface, skin_kept.keep));
  result.bone = in_metres(select_triangles(bone.surface, bone_kept.keep));
  result.seconds_check = seconds_since(stage);

  result.report = {
      {"file", plan.image.string()},
      {"read", image.description},
      {"size", image.size},
      {"spacing", {image.spacing.x(), image.spacing.y(), image.spacing.z()}},
      {"origin", {image.origin.x(), image.origin.y(), image.origin.z()}},
      {"value_range", {low, high}},
      {"iso", {{"skin", plan.skin_iso}, {"bone", plan.bone_iso}}},
      {"isosurface_criteria",
       {{"facet_size", options.facet_size},
        {"facet_distance", options.facet_distance},
        {"facet_angle", options.facet_angle},
        {"chosen",
         "facet_size: the model's layer thickness (max_thickness / layers), at least two voxels; "
         "facet_distance: decimation.max_error, else 0.5 mm, at least half a voxel; a plan's "
         "isosurface keys override them"}}},
      {"isosurface_triangles",
       {{"skin", skin.surface.triangles.size()}, {"bone", bone.surface.triangles.size()}}},
      {"every_region_seeded",
       {{"skin", skin.every_region_seeded}, {"bone", bone.every_region_seeded}}},
      {"scan_border_triangles_left_out",
       {{"skin", skin.border_triangles}, {"bone", bone.border_triangles}}},
      {"components", {{"skin", skin_kept.report}, {"bone", bone_kept.report}}},
      {"surface_distance_mm",
       {{"skin", distance_report(skin_distance, options.facet_distance)},
        {"bone", distance_report(bone_distance, options.facet_distance)}}}};
  return result;
}

}  // namespace incise::planning
