// Offscreen OpenGL pictures (EGL, Mesa's surfaceless platform): the default scene drawn as a
// user would see it. Skipped where no OpenGL can be had, unless INCISE_REQUIRE_GL is set (CI
// sets it: there the pictures must be made).

#include "incise/render/offscreen.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <thread>

#include "incise/render/camera.hpp"
#include "incise/view/frame_scene.hpp"
#include "incise/view/render_sink.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

std::unique_ptr<OffscreenRenderer> make_renderer() {
  try {
    return std::make_unique<OffscreenRenderer>();
  } catch (const Error& error) {
    if (std::getenv("INCISE_REQUIRE_GL") != nullptr) {
      ADD_FAILURE() << "INCISE_REQUIRE_GL is set and: " << error.what();
    }
    return nullptr;
  }
}

#define REQUIRE_RENDERER(name)                                   \
  const auto name = make_renderer();                             \
  if (!(name)) {                                                 \
    GTEST_SKIP() << "no OpenGL 3.3 through EGL on this machine"; \
  }

Rgba background() {
  return RenderOptions{}.background;
}

/// A pixel of cut tissue: deep red, unlike the background, the grey blade and the pale
/// exterior.
bool cut_coloured(const Rgba& p) {
  return p.r > 40 && p.r > 2 * p.g && p.r > 2 * p.b;
}

template <typename Predicate>
std::size_t count(const Image& image, const Predicate& predicate) {
  std::size_t n = 0;
  for (const Rgba& p : image.pixels()) {
    n += predicate(p) ? 1 : 0;
  }
  return n;
}

std::size_t body_pixels(const Image& image) {
  std::size_t n = 0;
  for (const Rgba& p : image.pixels()) {
    n += p == background() ? 0 : 1;
  }
  return n;
}

/// The default scene run with pictures of its first and last frame in `mode`.
std::pair<Image, Image> first_and_last(OffscreenRenderer& renderer, RenderMode mode,
                                       const std::string& name) {
  const auto dir = test::scratch_dir(name);
  SceneDescription scene = default_scene();
  Engine engine(scene);
  PictureOptions options;
  options.dir = dir;
  options.every = 1000;
  options.render.width = 320;
  options.render.height = 240;
  options.render.mode = mode;
  RenderSink sink(renderer, options);
  engine.add_sink(sink);
  (void)run(engine, scene.frames);
  EXPECT_EQ(sink.pictures().size(), 2u);
  return {read_png(sink.pictures().front()), read_png(sink.pictures().back())};
}

TEST(Offscreen, TheDefaultSceneIsDrawnAndNotBlank) {
  REQUIRE_RENDERER(renderer);
  EXPECT_FALSE(renderer->device().empty());
  const auto [first, last] = first_and_last(*renderer, RenderMode::kFaces, "faces");
  for (const Image* image : {&first, &last}) {
    const double share =
        static_cast<double>(body_pixels(*image)) / static_cast<double>(image->pixels().size());
    EXPECT_GT(share, 0.15) << "the body fills too little of the picture";
    EXPECT_LT(share, 0.9);
  }
}

TEST(Offscreen, ARendererMovesBetweenThreadsOneAtATime) {
  // Made on this thread, drawing on a second, then here again, deleted on a third (as Python's
  // render() from any thread does). Before, its context stayed current on the thread that made
  // it: the second thread could not take it, and a renderer made there deleted this one's GL
  // objects by their names in its own context.
  std::unique_ptr<OffscreenRenderer> renderer = make_renderer();
  if (!renderer) {
    GTEST_SKIP() << "no OpenGL 3.3 through EGL on this machine";
  }
  const Engine engine(default_scene());
  const FrameScene scene = frame_scene(engine);
  RenderOptions options;
  options.width = 160;
  options.height = 120;
  options.camera = fit_camera(scene.bounds(), 160.0 / 120.0);
  const Image here = renderer->render(scene.input(), options);
  EXPECT_GT(body_pixels(here), 2000u);
  Image there;
  std::string error;
  std::thread([&] {
    try {
      there = renderer->render(scene.input(), options);
      OffscreenRenderer own;  // another renderer made and deleted on that thread meanwhile
      (void)own.render(scene.input(), options);
    } catch (const Error& failure) {
      error = failure.what();
    }
  }).join();
  EXPECT_EQ(error, "");
  EXPECT_TRUE(there.pixels() == here.pixels());
  EXPECT_TRUE(renderer->render(scene.input(), options).pixels() == here.pixels());
  std::thread([&] { renderer.reset(); }).join();
}

TEST(Offscreen, CutModeShowsNoCutFaceBeforeTheCutAndTheWoundAfter) {
  REQUIRE_RENDERER(renderer);
  const auto [first, last] = first_and_last(*renderer, RenderMode::kCut, "cut");
  EXPECT_EQ(count(first, cut_coloured), 0u);
  EXPECT_GT(count(last, cut_coloured), 300u);
  // Only cut faces are drawn in this mode: the exterior's pale pink tissue is nowhere (the
  // blade is grey-blue, b >= r).
  const auto pale_pink = [](const Rgba& p) { return p.r > 120 && 2 * p.g > p.r && p.r > p.b + 25; };
  EXPECT_EQ(count(last, pale_pink), 0u);
  EXPECT_GT(count(first_and_last(*renderer, RenderMode::kFaces, "pink").first, pale_pink), 2000u);
}

TEST(Offscreen, FacesModeChangesWhereTheCutOpened) {
  REQUIRE_RENDERER(renderer);
  const auto [cut_first, cut_last] = first_and_last(*renderer, RenderMode::kCut, "cut-region");
  const auto [first, last] = first_and_last(*renderer, RenderMode::kFaces, "faces-region");
  // Where the wound shows in cut mode, the textured picture changed between first and last.
  std::size_t wound = 0;
  std::size_t changed = 0;
  for (std::size_t i = 0; i < cut_last.pixels().size(); ++i) {
    if (!cut_coloured(cut_last.pixels()[i])) {
      continue;
    }
    ++wound;
    const Rgba& a = first.pixels()[i];
    const Rgba& b = last.pixels()[i];
    changed += std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b) > 30 ? 1 : 0;
  }
  ASSERT_GT(wound, 300u);
  EXPECT_GT(changed, wound / 4);
  EXPECT_GT(count(last, cut_coloured), count(first, cut_coloured));
}

TEST(Offscreen, AScalarIsDrawnInTheColourMapBlueLowRedHigh) {
  REQUIRE_RENDERER(renderer);
  // A square facing the camera, its left half at the low end of the range, its right at the
  // high end.
  const std::vector<Vec3> positions{Vec3(-1, 0, -1), Vec3(0, 0, -1), Vec3(1, 0, -1),
                                    Vec3(-1, 0, 1),  Vec3(0, 0, 1),  Vec3(1, 0, 1)};
  const std::vector<Triangle> triangles{{0, 1, 4}, {0, 4, 3}, {1, 2, 5}, {1, 5, 4}};
  const std::vector<std::uint8_t> on_cut(triangles.size(), 0);
  const std::vector<double> scalars{0.0, 0.5, 1.0, 0.0, 0.5, 1.0};
  RenderInput input;
  input.triangles = triangles;
  input.on_cut = on_cut;
  input.positions = positions;
  input.rest_positions = positions;
  input.scalars = scalars;
  RenderOptions options;
  options.width = 200;
  options.height = 100;
  Bounds box;
  for (const Vec3& p : positions) {
    box.add(p);
  }
  options.camera = fit_camera(box, 2.0, -Vec3::UnitY(), Vec3::UnitZ(), 1.0);
  const Image image = renderer->render(input, options);
  // The square spans about 70 pixels across the middle (its box's sphere fills the height).
  const Rgba left = image.at(75, 50);
  const Rgba right = image.at(125, 50);
  EXPECT_GT(left.b, left.r + 40) << "the low end is blue";
  EXPECT_GT(right.r, right.b + 40) << "the high end is red";
}

TEST(Offscreen, TheSameFrameGivesTheSamePictureAtAnySizeAsked) {
  REQUIRE_RENDERER(renderer);
  Engine engine(default_scene());
  for (int k = 0; k < 40; ++k) {
    ASSERT_TRUE(engine.step());
  }
  const FrameScene scene = frame_scene(engine, true);
  RenderOptions options;
  options.width = 200;
  options.height = 150;
  options.mode = RenderMode::kWire;
  options.camera = fit_camera(scene.bounds(), 4.0 / 3);
  const Image a = renderer->render(scene.input(), options);
  options.width = 64;
  options.height = 48;
  const Image small = renderer->render(scene.input(), options);
  EXPECT_EQ(small.width(), 64);
  EXPECT_EQ(small.height(), 48);
  options.width = 200;
  options.height = 150;
  const Image b = renderer->render(scene.input(), options);
  EXPECT_EQ(a.pixels(), b.pixels());
  EXPECT_GT(body_pixels(a), 2000u);
}

TEST(Offscreen, SkippingTheBackFacesOfAClosedBodyLeavesThePictureAsItWas) {
  REQUIRE_RENDERER(renderer);
  Engine engine(default_scene());
  for (int k = 0; k < 150; ++k) {
    ASSERT_TRUE(engine.step());
  }
  const FrameScene scene = frame_scene(engine, false);
  ASSERT_FALSE(engine.cut_surface().empty());
  RenderOptions options;
  options.width = 240;
  options.height = 180;
  options.camera = fit_camera(scene.bounds(), 4.0 / 3);
  // All around the cut body and from below, in both modes that draw the exterior: where the
  // surface is closed the back faces lie behind front faces, so drawing them changes nothing
  // but the odd pixel on a silhouette edge.
  for (const RenderMode mode : {RenderMode::kFaces, RenderMode::kWire}) {
    options.mode = mode;
    for (int view = 0; view < 6; ++view) {
      orbit(options.camera, 1.05, view == 3 ? -1.2 : 0.0);
      options.two_sided = false;
      const Image culled = renderer->render(scene.input(), options);
      options.two_sided = true;
      const Image two_sided = renderer->render(scene.input(), options);
      std::size_t differ = 0;
      for (std::size_t i = 0; i < culled.pixels().size(); ++i) {
        const Rgba& a = culled.pixels()[i];
        const Rgba& b = two_sided.pixels()[i];
        differ += std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b) > 30 ? 1 : 0;
      }
      const std::size_t body = body_pixels(two_sided);
      ASSERT_GT(body, 2000u);
      EXPECT_LT(differ, body / 200) << "view " << view << " in " << name_of(mode);
    }
  }
}

}  // namespace
}  // namespace incise
