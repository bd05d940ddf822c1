#include "plan_pictures.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "incise/core/error.hpp"
#include "incise/render/annotate.hpp"
#include "incise/render/image.hpp"

namespace incise::app {

namespace {

/// Labels in a light grey on the renderer's dark background.
constexpr Rgba kInk{235, 235, 235, 255};

/// Where a direction points, in the patient frame of CT and DICOM (LPS: x to the patient's
/// left, y to the back, z up), along one axis.
std::string side_of(Eigen::Index axis, bool positive) {
  switch (axis) {
    case 0:
      return positive ? "the patient's left (+x)" : "the patient's right (-x)";
    case 1:
      return positive ? "behind (+y)" : "the front (-y)";
    default:
      return positive ? "above (+z)" : "below (-z)";
  }
}

/// The view's name from the direction towards the camera: lateral, frontal, posterior,
/// superior or inferior along its main axis, oblique when a second axis has 40 % of it.
std::string view_name(const Vec3& towards_camera) {
  const Vec3 size = towards_camera.cwiseAbs();
  Eigen::Index main = 0;
  (void)size.maxCoeff(&main);
  Eigen::Index second = (main + 1) % 3;
  const Eigen::Index third = (main + 2) % 3;
  if (size[third] > size[second]) {
    second = third;
  }
  const bool oblique = size[second] > 0.4 * size[main];
  const char* names[3][2] = {
      {"lateral", "lateral"}, {"frontal", "posterior"}, {"inferior", "superior"}};
  const bool positive = towards_camera[main] > 0.0;
  std::string name = std::string(oblique ? "oblique " : "") + names[main][positive ? 1 : 0] +
                     " view, from " + side_of(main, positive);
  if (oblique) {
    name += " and " + side_of(second, towards_camera[second] > 0.0);
  }
  return name;
}

/// A title at the top left and the view's name under it.
void label(Image& image, const std::string& title, const std::string& view) {
  const int scale = std::max(1, image.height() / 300);
  const int line = kTextLineUnits * scale;
  draw_text(image, line / 2, line / 2, title, scale, kInk);
  draw_text(image, line / 2, line / 2 + line, view, scale, kInk);
}

}  // namespace

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
  const double aspect = static_cast<double>(width) / height;
  auto camera_from = [&](const Vec3& towards) {
    const Vec3 up = std::abs(towards.z()) > 0.9 ? Vec3::UnitY() : Vec3::UnitZ();
    return fit_camera(box, aspect, towards, up, /*fill=*/1.2);
  };
  const std::vector<std::uint8_t> exterior(summary.skin_triangles.size(), 0);
  RenderInput input;
  input.triangles = summary.skin_triangles;
  input.on_cut = exterior;
  input.rest_positions = summary.skin_before;
  const auto render = [&](std::span<const Vec3> positions, std::span<const double> scalars,
                          std::uint64_t revision) {
    input.positions = positions;
    input.scalars = scalars;
    input.surface_revision = revision;
    return renderer.render(input, options);
  };
  const auto save = [&](const char* name, const Image& image) {
    const std::filesystem::path path = dir / name;
    write_png(path, image);
    pictures.files.push_back(path);
  };
  const std::string bar_label = "displacement (mm)";
  auto displacement_picture = [&](const Vec3& towards) {
    options.camera = camera_from(towards);
    Image image = render(summary.skin_after, moved, 2);
    label(image, fmt::format("skin displacement (max {:.2f} mm)", pictures.largest_displacement_mm),
          view_name(towards));
    draw_colour_bar(image, 0.0, options.scalar_range[1], bar_label, kInk);
    return image;
  };

  // The view that faces the moved skin: before, after, side by side, and coloured.
  options.camera = camera_from(direction);
  const std::string facing = view_name(direction);
  Image before = render(summary.skin_before, {}, 1);
  Image after = render(summary.skin_after, {}, 1);
  label(before, "skin before (scanned)", facing);
  label(after, "skin after (predicted)", facing);
  save("skin_before.png", before);
  save("skin_after.png", after);
  save("skin_before_after.png", side_by_side(before, after, options.background));
  save("skin_displacement.png", displacement_picture(direction));
  // The views a surgeon names: frontal, and lateral from the side that moved more.
  save("skin_displacement_frontal.png", displacement_picture(-Vec3::UnitY()));
  save("skin_displacement_lateral.png",
       displacement_picture(direction.x() >= 0.0 ? Vec3::UnitX() : Vec3(-Vec3::UnitX())));
  return pictures;
}

}  // namespace incise::app
