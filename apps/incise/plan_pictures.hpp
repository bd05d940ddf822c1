#pragma once
// Pictures of a plan's prediction (`incise plan --render DIR`): the skin before and after,
// textured, alone and side by side, and after coloured by its displacement (ParaView's Cool to
// Warm, 0 mm blue to the largest red, with a colour bar in mm) from a camera that looks at the
// displacement-weighted centre of the skin; the displacement also from the front and the side.
// Each picture names what it shows and from where (the patient frame: LPS).

#include <filesystem>
#include <vector>

#include "incise/planning/plan.hpp"
#include "incise/render/renderer.hpp"

namespace incise::app {

struct PlanPictures {
  std::vector<std::filesystem::path> files;
  double largest_displacement_mm = 0.0;  ///< the red end of the colour map
};

/// Writes DIR/skin_before.png, skin_after.png, skin_displacement.png,
/// skin_displacement_frontal.png and skin_displacement_lateral.png at width x height, and
/// skin_before_after.png at twice the width.
PlanPictures write_plan_pictures(const planning::PlanSummary& summary,
                                 const std::filesystem::path& dir, int width, int height,
                                 ImageRenderer& renderer);

}  // namespace incise::app
