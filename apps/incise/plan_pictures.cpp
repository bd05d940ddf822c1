#include "plan_pictures.hpp"

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/render/image.hpp"

namespace incise::app {

PlanPictures write_plan_pictures(const planning::PlanSummary& summary,
                                 const std::filesystem::path& dir, int width, int height,
                                 ImageRenderer& renderer) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) {
    throw InputError(dir.string(), 0, "cannot make the picture folder: " + error.message());
  }
  const std::size_t n = summary.skin_before.size();
  std::vector<double> moved(n);  // mm
  std::size_t most = 0;          // the largest displacement: the red end
  Bounds box;
  for (std::size_t i = 0; i < n; ++i) {
    moved[i] = (summary.skin_after[i] - summary.skin_before[i]).norm() * 1e3;
    most = moved[i] > moved[most] ? i : most;
    box.add(summary.skin_before[i]);
    box.add(summary.skin_after[i]);
  }
  PlanPictures pictures;
  pictures.largest_displacement_mm = n > 0 ? moved[most] : 0.0;
  RenderOptions options;
  options.width = width;
  options.height = height;
  options.draw_blade = false;
  options.texture_period = 0.03;  // m: skin-sized tiles
  options.scalar_range = {0.0, std::max(pictures.largest_displacement_mm, 1e-9)};
  // From the side where the skin moves, the displacement-weighted centre of the skin (the
  // most displaced point may lie in a fold, an airway), z up unless it looks along z.
  Vec3 weighted = Vec3::Zero();
  double weight = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    weighted += moved[i] * summary.skin_before[i];
    weight += moved[i];
  }
  Vec3 direction = weight > 0.0 ? Vec3(weighted / weight - box.centre()) : Vec3::UnitY();
  if (!(direction.norm() > 0.0)) {
    direction = -Vec3::UnitY();
  }
  direction.normalize();
  const Vec3 up = std::abs(direction.z()) > 0.9 ? Vec3::UnitY() : Vec3::UnitZ();
  options.camera =
      fit_camera(box, static_cast<double>(width) / height, direction, up, /*fill=*/1.2);
  const std::vector<std::uint8_t> exterior(summary.skin_triangles.size(), 0);
  RenderInput input;
  input.triangles = summary.skin_triangles;
  input.on_cut = exterior;
  input.rest_positions = summary.skin_before;
  const auto draw = [&](const char* name, std::span<const Vec3> positions,
                        std::span<const double> scalars, std::uint64_t revision) {
    input.positions = positions;
    input.scalars = scalars;
    input.surface_revision = revision;
    const std::filesystem::path path = dir / name;
    write_png(path, renderer.render(input, options));
    pictures.files.push_back(path);
  };
  draw("skin_before.png", summary.skin_before, {}, 1);
  draw("skin_after.png", summary.skin_after, {}, 1);
  draw("skin_displacement.png", summary.skin_after, moved, 2);
  return pictures;
}

}  // namespace incise::app
