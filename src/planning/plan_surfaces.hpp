#pragma once
// A plan's skin and bone surfaces from its CT (private to planning): both isosurfaces meshed at
// once with criteria chosen from the image and the model (the mesher's facet distance is the
// plan's surface bound, so nothing is decimated afterwards), the components that are anatomy
// kept, and each surface measured against the isosurface both ways.

#include <nlohmann/json.hpp>

#include "incise/planning/plan.hpp"

namespace incise::planning {

struct PlanSurfaces {
  SurfaceMesh skin;  ///< m
  SurfaceMesh bone;  ///< m
  nlohmann::json report;
  double seconds_image = 0.0;
  double seconds_isosurface = 0.0;
  double seconds_check = 0.0;
};

/// A surface in millimetres (plans, CTs, surface files) in metres.
[[nodiscard]] SurfaceMesh in_metres(SurfaceMesh surface);

/// mm: the isosurface criteria a plan gets when it does not set them: triangles up to the
/// model's layer thickness (never under two voxels) and within the plan's surface bound
/// (decimation.max_error; 0.5 mm, never under half a voxel, when it has none).
[[nodiscard]] imaging::IsosurfaceOptions isosurface_criteria(const PlanDescription& plan,
                                                             const Vec3& spacing);

[[nodiscard]] PlanSurfaces surfaces_from_image(const PlanDescription& plan,
                                               const PlanProgress& progress);

}  // namespace incise::planning
