// The renderer without OpenGL: camera maths, solid textures, PNG files, and the buffers a
// backend is given as the engine cuts (the null backend records them).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "incise/cut/subdivision_cutter.hpp"
#include "incise/render/camera.hpp"
#include "incise/render/colour_map.hpp"
#include "incise/render/image.hpp"
#include "incise/render/renderer.hpp"
#include "incise/render/solid_texture.hpp"
#include "incise/view/frame_scene.hpp"
#include "incise/view/render_sink.hpp"
#include "scene_support.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

Eigen::Vector3d project(const Mat4& matrix, const Vec3& p) {
  const Eigen::Vector4d clip = matrix * Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
  return clip.head<3>() / clip.w();
}

Bounds box(const Vec3& low, const Vec3& high) {
  Bounds b;
  b.add(low);
  b.add(high);
  return b;
}

TEST(Camera, AFittedCameraSeesTheWholeBoxWithTheTargetInTheMiddle) {
  const Bounds body = box(Vec3(-0.02, 0.1, 0.0), Vec3(0.03, 0.16, 0.04));
  for (double aspect : {0.5, 1.0, 4.0 / 3.0, 2.5}) {
    const Camera camera = fit_camera(body, aspect);
    const Mat4 m = projection_matrix(camera, aspect, body) * view_matrix(camera);
    EXPECT_LT(project(m, body.centre()).head<2>().norm(), 1e-12);
    for (int corner = 0; corner < 8; ++corner) {
      const Vec3 p((corner & 1) ? body.max.x() : body.min.x(),
                   (corner & 2) ? body.max.y() : body.min.y(),
                   (corner & 4) ? body.max.z() : body.min.z());
      const Vec3 ndc = project(m, p);
      EXPECT_LT(ndc.cwiseAbs().maxCoeff(), 1.0) << "corner " << corner << " aspect " << aspect;
    }
  }
}

TEST(Camera, OrbitPanAndZoomMoveTheEyeAsAViewerExpects) {
  Camera camera = fit_camera(box(Vec3::Zero(), Vec3::Ones()), 1.0);
  const double distance = (camera.eye - camera.target).norm();
  const double height = camera.eye.z();
  orbit(camera, 0.3, 0.2);
  EXPECT_NEAR((camera.eye - camera.target).norm(), distance, 1e-12);
  EXPECT_GT(camera.eye.z(), height);  // pitching up raises the eye
  orbit(camera, 0.0, 10.0);           // stops short of the pole
  EXPECT_GT((camera.eye - camera.target).cross(camera.up).norm(), 1e-3);
  const Vec3 offset = camera.eye - camera.target;
  pan(camera, 0.1, -0.05);
  EXPECT_LT((camera.eye - camera.target - offset).norm(), 1e-12);  // eye and target together
  zoom(camera, 0.5);
  EXPECT_NEAR((camera.eye - camera.target).norm(), 0.5 * distance, 1e-12);
}

TEST(SolidTexture, TilesSeamlesslyIsRepeatableAndCutTissueIsRedder) {
  const SolidTexture exterior = make_tissue_texture(TissueLook::kExterior, 32);
  const SolidTexture cut = make_tissue_texture(TissueLook::kCut, 32);
  EXPECT_EQ(make_tissue_texture(TissueLook::kCut, 32).texels, cut.texels);
  // Across the wrap, neighbours differ no more than inside the texture.
  const auto step = [](const SolidTexture& t, int i0, int i1, int j, int k) {
    int sum = 0;
    for (int c = 0; c < 3; ++c) {
      sum += std::abs(t.at(i0, j, k)[c] - t.at(i1, j, k)[c]);
    }
    return sum;
  };
  for (const SolidTexture* texture : {&exterior, &cut}) {
    double across = 0.0;
    double inside = 0.0;
    for (int j = 0; j < 32; ++j) {
      for (int k = 0; k < 32; ++k) {
        across += step(*texture, 31, 0, j, k);
        inside += step(*texture, 15, 16, j, k);
      }
    }
    EXPECT_LT(across, 2.0 * inside + 32.0 * 32.0);
  }
  const auto redness = [](const SolidTexture& t) {
    double sum = 0.0;
    for (const auto& texel : t.texels) {
      sum += texel[0] - 0.5 * (texel[1] + texel[2]);
    }
    return sum / static_cast<double>(t.texels.size());
  };
  EXPECT_GT(redness(cut), redness(exterior) + 40.0);
}

TEST(Png, RoundTripsAndNamesABadFile) {
  const auto dir = test::scratch_dir("png");
  Image image(7, 5, Rgba{10, 20, 30, 255});
  image.at(6, 4) = Rgba{200, 100, 50, 128};
  write_png(dir / "a.png", image);
  const Image back = read_png(dir / "a.png");
  ASSERT_EQ(back.width(), 7);
  ASSERT_EQ(back.height(), 5);
  EXPECT_EQ(back.pixels(), image.pixels());
  std::ofstream(dir / "bad.png") << "not a picture";
  try {
    (void)read_png(dir / "bad.png");
    FAIL() << "a text file read as a PNG";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("bad.png"), std::string::npos) << error.what();
  }
  EXPECT_THROW(write_png(dir / "no" / "such" / "folder.png", image), InputError);
  EXPECT_FALSE(std::filesystem::exists(dir / "no"));
  EXPECT_THROW(Image(0, 10), InputError);
}

using test::short_default;

TEST(Renderer, BuffersFollowEveryCutAndEveryFaceHasTextureCoordinates) {
  Engine engine(short_default(150));
  NullBackend backend;
  Renderer renderer(backend);
  RenderOptions options;
  options.texture_period = 0.02;
  int surface_changes = 0;
  std::uint64_t revision = 0;
  for (int k = 0; k <= 150; ++k) {
    if (k > 0) {
      ASSERT_TRUE(engine.step()) << engine.divergence();
    }
    const FrameScene scene = frame_scene(engine);
    surface_changes += scene.surface->version != revision ? 1 : 0;
    revision = scene.surface->version;
    options.camera = fit_camera(scene.bounds(), 1.0);
    renderer.render(scene.input(), options);
    // Uploads: the surface once per change, positions every frame.
    ASSERT_EQ(backend.surface_uploads, surface_changes);
    ASSERT_EQ(backend.position_uploads, k + 1);
    const SurfaceBuffers& buffers = backend.surface;
    ASSERT_EQ(buffers.exterior_triangles + buffers.cut_triangles, scene.surface->triangles.size());
    ASSERT_EQ(buffers.indices.size(), 3 * scene.surface->triangles.size());
    ASSERT_EQ(buffers.texture_coordinates.size(), 3 * buffers.vertices.size());
    ASSERT_EQ(backend.positions.size(), 3 * buffers.vertices.size());
    // Every corner of every face has its vertex's rest position as texture coordinate.
    for (std::size_t corner = 0; corner < buffers.indices.size(); ++corner) {
      const std::uint32_t slot = buffers.indices[corner];
      ASSERT_LT(slot, buffers.vertices.size());
      const Vec3 rest = engine.mesh().rest_position(buffers.vertices[slot]);
      for (int c = 0; c < 3; ++c) {
        const float t = buffers.texture_coordinates[3 * slot + static_cast<std::size_t>(c)];
        ASSERT_TRUE(std::isfinite(t));
        ASSERT_NEAR(t, rest[c] / options.texture_period, 1e-4);
        ASSERT_NEAR(backend.positions[3 * slot + static_cast<std::size_t>(c)],
                    engine.positions()[static_cast<std::size_t>(buffers.vertices[slot])][c], 1e-6);
      }
    }
    // The cut faces are the engine's cut surface.
    ASSERT_EQ(buffers.cut_triangles, engine.cut_surface().size());
    // A tetrahedral mesh's boundary is closed and faces out after any cut, so its back faces
    // are skipped, except where only the cut faces are shown.
    ASSERT_TRUE(buffers.closed_outward) << "frame " << k;
    ASSERT_TRUE(backend.last_call.cull_back_faces);
  }
  EXPECT_GT(backend.surface.cut_triangles, 20u);
  EXPECT_GT(surface_changes, 10);
  EXPECT_LT(surface_changes, 152);  // not re-uploaded when nothing changed
  EXPECT_FALSE(backend.last_call.blade_quad.empty());
}

TEST(Renderer, BackFacesAreSkippedOnlyWhereTheSurfaceIsClosedAndFacesOut) {
  // Two tetrahedra touching along one edge (0-1), each with its four faces outward.
  const std::vector<Vec3> positions{Vec3(0, 0, 0), Vec3(1, 0, 0),  Vec3(0, 1, 0),
                                    Vec3(0, 0, 1), Vec3(0, -1, 0), Vec3(0, 0, -1)};
  const auto faces_of = [](VertexId a, VertexId b, VertexId c, VertexId d) {
    return std::vector<Triangle>{{a, c, b}, {a, b, d}, {a, d, c}, {b, c, d}};
  };
  std::vector<Triangle> closed = faces_of(0, 1, 2, 3);
  for (const Triangle& t : faces_of(0, 1, 4, 5)) {
    closed.push_back(t);
  }
  EXPECT_TRUE(closed_and_facing_out(closed, positions));
  std::vector<Triangle> inward = closed;
  for (Triangle& t : inward) {
    std::swap(t[1], t[2]);
  }
  EXPECT_FALSE(closed_and_facing_out(inward, positions)) << "closed, but facing in";
  std::vector<Triangle> open(closed.begin() + 1, closed.end());
  EXPECT_FALSE(closed_and_facing_out(open, positions)) << "a face missing";
  std::vector<Triangle> flipped = closed;
  std::swap(flipped[5][1], flipped[5][2]);
  EXPECT_FALSE(closed_and_facing_out(flipped, positions)) << "one face turned the wrong way";
  EXPECT_FALSE(closed_and_facing_out({}, positions));

  // The renderer culls the closed pair in faces mode, never in cut mode or when asked not to.
  const std::vector<std::uint8_t> on_cut(closed.size(), 0);
  RenderInput input;
  input.triangles = closed;
  input.on_cut = on_cut;
  input.positions = positions;
  input.rest_positions = positions;
  NullBackend backend;
  Renderer renderer(backend);
  RenderOptions options;
  options.camera = fit_camera(box(Vec3(-1, -1, -1), Vec3(1, 1, 1)), 1.0);
  renderer.render(input, options);
  EXPECT_TRUE(backend.last_call.cull_back_faces);
  options.mode = RenderMode::kCut;
  renderer.render(input, options);
  EXPECT_FALSE(backend.last_call.cull_back_faces);
  options.mode = RenderMode::kFaces;
  options.two_sided = true;
  renderer.render(input, options);
  EXPECT_FALSE(backend.last_call.cull_back_faces);
  options.two_sided = false;
  input.triangles = open;
  input.on_cut = std::span<const std::uint8_t>(on_cut).first(open.size());
  input.surface_revision = 1;
  renderer.render(input, options);
  EXPECT_FALSE(backend.last_call.cull_back_faces);
}

TEST(Renderer, HighlightsTheActiveTetrahedraAndTheEdgesTheBladeHasCut) {
  Engine engine(short_default(75));
  for (int k = 0; k < 75; ++k) {
    ASSERT_TRUE(engine.step());
  }
  ASSERT_FALSE(engine.cutter()->active_tets().empty());
  const FrameScene plain = frame_scene(engine);
  EXPECT_TRUE(plain.highlights.empty());
  const FrameScene scene = frame_scene(engine, true);
  EXPECT_EQ(scene.highlights.size() + scene.cut_edges.size(),
            6 * engine.cutter()->active_tets().size());
  EXPECT_FALSE(scene.cut_edges.empty());  // the blade is in the middle of the block
  NullBackend backend;
  Renderer renderer(backend);
  RenderOptions options;
  options.camera = fit_camera(scene.bounds(), 1.0);
  renderer.render(scene.input(), options);
  EXPECT_EQ(backend.last_call.lines.size(), 6 * scene.highlights.size());
  EXPECT_EQ(backend.last_call.cut_lines.size(), 6 * scene.cut_edges.size());
}

TEST(Renderer, ATriangleOutsideThePositionsIsAnErrorNamingIt) {
  const std::vector<Vec3> positions{Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY()};
  const std::vector<Triangle> triangles{{0, 1, 2}, {0, 2, 7}};
  const std::vector<std::uint8_t> on_cut{0, 1};
  RenderInput input;
  input.triangles = triangles;
  input.on_cut = on_cut;
  input.positions = positions;
  input.rest_positions = positions;
  try {
    (void)build_surface_buffers(input, 0.02);
    FAIL() << "a triangle with a vertex that has no position";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("triangle 1"), std::string::npos) << error.what();
  }
}

TEST(Renderer, ASurfaceThatLostVerticesUnderTheSameRevisionIsBuiltAgainNotReadPastItsEnd) {
  // The planning window drew a plane's disc after the bone's corners, then the bone alone
  // under the same revision: the buffers in hand still held the disc's vertices, and the
  // positions were read past their end (here, into a NaN the span does not include).
  const std::vector<Vec3> storage{Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ(),
                                  Vec3::Constant(std::nan(""))};
  const std::vector<Triangle> with_disc{{0, 1, 2}, {1, 2, 3}};
  const std::vector<Triangle> without{{0, 1, 2}};
  const std::vector<std::uint8_t> on_cut{0, 0};
  NullBackend backend;
  Renderer renderer(backend);
  RenderOptions options;
  options.camera = fit_camera(Bounds{Vec3::Zero(), Vec3::Ones()}, 1.0);
  RenderInput input;
  input.surface_revision = 7;
  input.triangles = with_disc;
  input.on_cut = on_cut;
  input.positions = std::span<const Vec3>(storage).first(4);
  input.rest_positions = input.positions;
  renderer.render(input, options);
  EXPECT_EQ(backend.surface_uploads, 1);
  input.triangles = without;
  input.on_cut = std::span<const std::uint8_t>(on_cut).first(1);
  input.positions = std::span<const Vec3>(storage).first(3);
  input.rest_positions = input.positions;
  EXPECT_NO_THROW(renderer.render(input, options));
  EXPECT_EQ(backend.surface_uploads, 2);
}

TEST(ColourMap, CoolToWarmRunsFromBlueThroughGreyToRedAndClamps) {
  EXPECT_EQ(cool_to_warm(0.0), (Rgba{59, 76, 192, 255}));
  EXPECT_EQ(cool_to_warm(0.5), (Rgba{221, 221, 221, 255}));
  EXPECT_EQ(cool_to_warm(1.0), (Rgba{180, 4, 38, 255}));
  EXPECT_EQ(cool_to_warm(-3.0), cool_to_warm(0.0));
  EXPECT_EQ(cool_to_warm(7.0), cool_to_warm(1.0));
  EXPECT_EQ(cool_to_warm(std::nan("")), cool_to_warm(0.0));
  // Diverging: blue below the middle, red above it, lightest in the middle.
  const auto lightness = [](const Rgba& c) { return c.r + c.g + c.b; };
  for (double t = 0.0; t < 0.99; t += 0.05) {
    const Rgba a = cool_to_warm(t);
    const Rgba b = cool_to_warm(t + 0.05);
    if (t < 0.45) {
      EXPECT_GT(a.b, a.r) << t;
      EXPECT_LT(lightness(a), lightness(b)) << t;
    } else if (t > 0.55) {
      EXPECT_GT(a.r, a.b) << t;
      EXPECT_GT(lightness(a), lightness(b)) << t;
    }
  }
  const std::vector<std::uint8_t> texels = colour_map_texels(5);
  ASSERT_EQ(texels.size(), 15U);
  EXPECT_EQ(texels[6], 221);  // the middle texel is the grey
}

TEST(Renderer, AScalarColoursTheSurfaceThroughTheColourMapAndFollowsItsRange) {
  const std::vector<Vec3> positions{Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  const std::vector<Triangle> triangles{{0, 1, 2}, {0, 2, 3}};
  const std::vector<std::uint8_t> on_cut{0, 0};
  const std::vector<double> scalars{0.0, 2.0, 4.0, 9.0};
  RenderInput input;
  input.triangles = triangles;
  input.on_cut = on_cut;
  input.positions = positions;
  input.rest_positions = positions;
  input.scalars = scalars;
  NullBackend backend;
  Renderer renderer(backend);
  RenderOptions options;
  options.scalar_range = {0.0, 4.0};
  renderer.render(input, options);
  ASSERT_TRUE(backend.surface.colour_mapped);
  EXPECT_TRUE(backend.last_call.colour_mapped);
  for (std::size_t k = 0; k < backend.surface.vertices.size(); ++k) {
    const double expected =
        std::min(scalars[static_cast<std::size_t>(backend.surface.vertices[k])] / 4.0, 1.0);
    EXPECT_FLOAT_EQ(backend.surface.texture_coordinates[3 * k], static_cast<float>(expected));
    EXPECT_FLOAT_EQ(backend.surface.texture_coordinates[3 * k + 1], 0.5F);
  }
  // A new range is a new upload; the same one is not.
  renderer.render(input, options);
  EXPECT_EQ(backend.surface_uploads, 1);
  options.scalar_range = {0.0, 9.0};
  renderer.render(input, options);
  EXPECT_EQ(backend.surface_uploads, 2);
  // Without scalars, textured again.
  input.scalars = {};
  renderer.render(input, options);
  EXPECT_EQ(backend.surface_uploads, 3);
  EXPECT_FALSE(backend.last_call.colour_mapped);
  // A vertex without a scalar is named.
  const std::vector<double> short_scalars{1.0, 2.0};
  input.scalars = short_scalars;
  try {
    (void)build_surface_buffers(input, 0.02);
    FAIL() << "a vertex without a scalar";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("no scalar"), std::string::npos) << error.what();
  }
}

/// An ImageRenderer that paints the count of cut triangles into the first pixel.
class CountingRenderer final : public ImageRenderer {
 public:
  Image render(const RenderInput& input, const RenderOptions& options) override {
    Image image(options.width, options.height);
    std::size_t cut = 0;
    for (std::uint8_t mark : input.on_cut) {
      cut += mark;
    }
    image.at(0, 0).r = static_cast<std::uint8_t>(std::min<std::size_t>(cut, 255));
    cameras.push_back(options.camera);
    return image;
  }
  std::vector<Camera> cameras;
};

TEST(RenderSink, DrawsTheFirstEveryNthAndTheLastFrameWithOneCamera) {
  const auto dir = test::scratch_dir("pictures");
  Engine engine(short_default(23));
  CountingRenderer renderer;
  PictureOptions options;
  options.dir = dir;
  options.every = 10;
  options.render.width = 32;
  options.render.height = 24;
  RenderSink sink(renderer, options);
  engine.add_sink(sink);
  (void)run(engine, 23);
  std::vector<std::string> names;
  for (const auto& path : sink.pictures()) {
    names.push_back(path.filename().string());
    EXPECT_TRUE(std::filesystem::exists(path));
  }
  EXPECT_EQ(names, (std::vector<std::string>{"frame_000000.png", "frame_000010.png",
                                             "frame_000020.png", "frame_000023.png"}));
  EXPECT_EQ(read_png(dir / "frame_000000.png").at(0, 0).r, 0);  // nothing cut yet
  EXPECT_GT(read_png(dir / "frame_000023.png").at(0, 0).r, 0);
  for (const Camera& camera : renderer.cameras) {
    EXPECT_EQ(camera.eye, renderer.cameras.front().eye);
  }
}

}  // namespace
}  // namespace incise
