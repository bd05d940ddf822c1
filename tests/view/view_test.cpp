// The viewer's parts that need no window: the mouse scalpel's geometry, the hand-over from the
// scene's path to the mouse, and session recordings that replay a hand-made cut bit for bit.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "incise/mesh/validate.hpp"
#include "incise/view/frame_scene.hpp"
#include "incise/view/mouse_scalpel.hpp"
#include "incise/view/session_recording.hpp"
#include "incise/xfem/visual_surface.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

Eigen::Vector2d to_screen(const Camera& camera, double aspect, const Bounds& scene, const Vec3& p) {
  const Eigen::Vector4d clip = projection_matrix(camera, aspect, scene) * view_matrix(camera) *
                               Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
  return clip.head<2>() / clip.w();
}

Bounds unit_box() {
  Bounds box;
  box.add(Vec3::Zero());
  box.add(Vec3::Ones());
  return box;
}

TEST(MouseScalpel, TheCursorRayProjectsBackToTheCursor) {
  const Camera camera = fit_camera(unit_box(), 1.5);
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {0.0, 0.0}, {0.5, -0.3}, {-0.9, 0.9}, {0.99, -0.99}}) {
    const Ray ray = cursor_ray(camera, 1.5, x, y);
    EXPECT_NEAR(ray.direction.norm(), 1.0, 1e-12);
    const Eigen::Vector2d back = to_screen(camera, 1.5, unit_box(), ray.origin + ray.direction);
    EXPECT_NEAR(back.x(), x, 1e-9);
    EXPECT_NEAR(back.y(), y, 1e-9);
  }
}

TEST(MouseScalpel, PicksTheNearestFaceAndMissesBesideTheBody) {
  // Two parallel squares, z = 0 and z = 1, seen from above.
  const std::vector<Vec3> positions{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                    {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const std::vector<Triangle> triangles{{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
  const Ray down{Vec3(0.3, 0.6, 5.0), Vec3(0, 0, -1)};
  const auto hit = pick_surface(down, triangles, positions);
  ASSERT_TRUE(hit.has_value());
  EXPECT_GE(hit->triangle, 2u);  // the upper square, not the one behind it
  EXPECT_NEAR(hit->point.z(), 1.0, 1e-12);
  EXPECT_NEAR(hit->distance, 4.0, 1e-12);
  EXPECT_FALSE(pick_surface({Vec3(1.5, 0.5, 5.0), Vec3(0, 0, -1)}, triangles, positions));
  EXPECT_FALSE(pick_surface({Vec3(0.5, 0.5, 5.0), Vec3(0, 0, 1)}, triangles, positions));
}

TEST(MouseScalpel, ADragFollowsTheCursorOnThePlaneThroughWhereItStarted) {
  // What a dragged bone segment follows: the cursor's point on the plane facing the camera
  // through the picked point. Where the drag starts it is the picked point; moved across the
  // screen, the point stays at the picked point's depth and projects back under the cursor.
  const Camera camera = fit_camera(unit_box(), 1.5);
  const Vec3 anchor(0.3, 0.6, 0.7);
  const Eigen::Vector2d at = to_screen(camera, 1.5, unit_box(), anchor);
  const Vec3 start = point_on_anchor_plane(camera, cursor_ray(camera, 1.5, at.x(), at.y()), anchor);
  EXPECT_NEAR((start - anchor).norm(), 0.0, 1e-9);
  const Vec3 forward = (camera.target - camera.eye).normalized();
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{0.2, 0.1}, {-0.5, 0.4}}) {
    const Vec3 moved = point_on_anchor_plane(camera, cursor_ray(camera, 1.5, x, y), anchor);
    EXPECT_NEAR((moved - anchor).dot(forward), 0.0, 1e-9);  // the same depth
    const Eigen::Vector2d back = to_screen(camera, 1.5, unit_box(), moved);
    EXPECT_NEAR(back.x(), x, 1e-9);
    EXPECT_NEAR(back.y(), y, 1e-9);
  }
}

TEST(MouseScalpel, ATurnOnTheScreenIsTheAngleTheCursorSweptAboutTheCentre) {
  const Camera camera = fit_camera(unit_box(), 1.5);
  const Vec3 centre(0.4, 0.5, 0.6);
  const Eigen::Vector2d at = to_screen(camera, 1.5, unit_box(), centre);
  const auto ray = [&](double dx, double dy) {
    return cursor_ray(camera, 1.5, at.x() + dx, at.y() + dy);
  };
  // From the right of the centre to above it: a quarter turn, counter-clockwise on the screen.
  EXPECT_NEAR(turn_on_screen(camera, centre, ray(0.2, 0.0), ray(0.0, 0.3)), 0.5 * std::numbers::pi,
              1e-9);
  EXPECT_NEAR(turn_on_screen(camera, centre, ray(0.0, 0.3), ray(0.2, 0.0)), -0.5 * std::numbers::pi,
              1e-9);
  EXPECT_NEAR(turn_on_screen(camera, centre, ray(0.2, 0.0), ray(0.4, 0.0)), 0.0, 1e-9);
  // Turned by that angle about the axis towards the camera, the press point lands under the
  // cursor's ray again.
  const Ray from = ray(0.1, -0.2);
  const Ray to = ray(-0.3, 0.05);
  const double angle = turn_on_screen(camera, centre, from, to);
  const Vec3 pressed = point_on_anchor_plane(camera, from, centre);
  const Vec3 turned =
      centre + Eigen::AngleAxisd(angle, towards_camera(camera)) * (pressed - centre);
  const Vec3 reached = point_on_anchor_plane(camera, to, centre);
  EXPECT_NEAR((turned - centre).normalized().dot((reached - centre).normalized()), 1.0, 1e-12);
  // The cursor on the centre itself: no turn.
  EXPECT_EQ(turn_on_screen(camera, centre, ray(0.0, 0.0), ray(0.2, 0.1)), 0.0);
}

TEST(MouseScalpel, TheBladeCrossesTheAnchorPlaneUnderTheCursorWithItsDepth) {
  const Camera camera = fit_camera(unit_box(), 1.0);
  const Vec3 forward = (camera.target - camera.eye).normalized();
  const Vec3 anchor(0.5, 0.4, 0.9);
  const Ray ray = cursor_ray(camera, 1.0, 0.2, -0.1);
  const BladePose pose = scalpel_pose(camera, ray, anchor, 0.3, 0.5);
  EXPECT_NEAR((pose.tip - pose.base).norm(), 0.8, 1e-12);
  // The blade crosses the plane on the cursor's ray.
  const double at_tip = (pose.tip - anchor).dot(forward);
  const double at_base = (pose.base - anchor).dot(forward);
  ASSERT_GT(at_tip, 0.0);  // the tip is beyond the plane, into the body
  ASSERT_LT(at_base, 0.0);
  const Vec3 crossing = pose.base + at_base / (at_base - at_tip) * (pose.tip - pose.base);
  EXPECT_LT((crossing - ray.origin).cross(ray.direction).norm(), 1e-12);
  // Seen from the camera it is a line, not a point.
  const auto a = to_screen(camera, 1.0, unit_box(), pose.tip);
  const auto b = to_screen(camera, 1.0, unit_box(), pose.base);
  EXPECT_GT((a - b).norm(), 0.05);
}

/// The default scene stepped with the scene's path for 20 frames, then cut by "hand": two
/// strokes made of cursor positions, lifted between them.
struct HandCut {
  SessionRecording recording;
  std::vector<Vec3> positions;
  std::size_t tets = 0;
  std::size_t tets_when_taken = 0;
};

HandCut cut_by_hand() {
  HandCut result;
  SceneDescription scene = default_scene();
  Engine engine(scene);
  auto tool = std::make_unique<HandOverTool>(std::make_unique<ScriptedToolPath>(scene.tool.poses));
  HandOverTool& hand = *tool;
  engine.set_tool_source(std::move(tool));
  SessionRecorder recorder(result.recording);
  engine.add_sink(recorder);
  for (int k = 0; k < 20; ++k) {
    EXPECT_TRUE(engine.step());
  }
  hand.take();
  recorder.action(engine.frame(), "take");
  result.tets_when_taken = engine.mesh().tet_count();
  const FrameScene view = frame_scene(engine);
  const Bounds body = view.bounds();
  const Camera camera = fit_camera(body, 1.0, Vec3(0.1, -0.4, 1.0));  // from above
  for (int stroke = 0; stroke < 2; ++stroke) {
    const double y = stroke == 0 ? -0.1 : 0.12;
    std::optional<Vec3> anchor;
    for (int k = 0; k <= 30; ++k) {
      const Ray ray = cursor_ray(camera, 1.0, -0.3 + 0.6 * k / 30.0, y);
      if (!anchor) {  // the press: on the body
        const FrameScene now = frame_scene(engine);
        const auto hit = pick_surface(ray, now.surface->triangles, now.positions);
        if (!hit) {
          ADD_FAILURE() << "the stroke does not start on the body";
          return result;
        }
        anchor = hit->point;
      }
      hand.live().set(scalpel_pose(camera, ray, *anchor, 0.012, 0.02));
      EXPECT_TRUE(engine.step()) << engine.divergence();
    }
    hand.live().lift();
    for (int k = 0; k < 5; ++k) {
      EXPECT_TRUE(engine.step());
    }
  }
  engine.finish();
  result.positions.assign(engine.positions().begin(), engine.positions().end());
  result.tets = engine.mesh().tet_count();
  const ValidationReport report = validate(engine.mesh());
  EXPECT_TRUE(report.ok()) << report.describe();
  return result;
}

TEST(SessionRecording, AHandMadeCutReplaysBitForBitFromTheFile) {
  const HandCut original = cut_by_hand();
  EXPECT_GT(original.tets, original.tets_when_taken + 50) << "the mouse strokes did not cut";
  const auto dir = test::scratch_dir("session");
  write_session(dir / "cut.jsonl", original.recording);
  const SessionRecording read = read_session(dir / "cut.jsonl");
  ASSERT_EQ(read.segments.size(), 1u);
  const SessionSegment& segment = read.segments.front();
  EXPECT_EQ(segment.frames(), 20 + 2 * 36);
  ASSERT_EQ(segment.actions.size(), 1u);
  EXPECT_EQ(segment.actions.front().frame, 20);
  EXPECT_EQ(segment.actions.front().name, "take");
  // The scene's path is in the rest frame, the mouse's poses in the world (the picture).
  ASSERT_EQ(segment.world.size(), segment.poses.size());
  for (std::size_t frame = 0; frame < segment.poses.size(); ++frame) {
    if (segment.poses[frame]) {
      EXPECT_EQ(segment.world[frame] != 0, frame > 20) << "frame " << frame;
    }
  }
  const auto engine = replay_engine(segment);
  for (int k = 0; k < segment.frames(); ++k) {
    ASSERT_TRUE(engine->step());
  }
  EXPECT_EQ(engine->mesh().tet_count(), original.tets);
  ASSERT_EQ(engine->positions().size(), original.positions.size());
  for (std::size_t i = 0; i < original.positions.size(); ++i) {
    ASSERT_EQ(engine->positions()[i], original.positions[i]) << "vertex " << i;
  }
}

// A quick stroke made between two frames (a click-drag-release faster than the physics)
// cuts, is recorded with the poses it passed through, and replays bit for bit.
TEST(SessionRecording, AStrokeMadeBetweenTwoFramesIsRecordedAndReplayed) {
  SessionRecording recording;
  SceneDescription scene = default_scene();
  scene.tool.poses.clear();
  Engine engine(scene);
  auto tool = std::make_unique<HandOverTool>(nullptr);
  HandOverTool& hand = *tool;
  engine.set_tool_source(std::move(tool));
  SessionRecorder recorder(recording);
  engine.add_sink(recorder);
  hand.take();
  ASSERT_TRUE(engine.step());
  const std::size_t tets_before = engine.mesh().tet_count();
  for (int k = 0; k <= 10; ++k) {
    const double y = -0.01 + 0.005 * k;
    hand.live().set(BladePose{0.0, Vec3(0.0213, y, 0.012), Vec3(0.0213, y, 0.06)});
  }
  hand.live().lift();
  ASSERT_TRUE(engine.step());
  ASSERT_TRUE(engine.step());
  engine.finish();
  EXPECT_GT(engine.mesh().tet_count(), tets_before + 20);

  const auto dir = test::scratch_dir("session-through");
  write_session(dir / "quick.jsonl", recording);
  const SessionRecording read = read_session(dir / "quick.jsonl");
  ASSERT_EQ(read.segments.size(), 1u);
  const SessionSegment& segment = read.segments.front();
  ASSERT_GE(segment.passed.size(), 3u);
  EXPECT_EQ(segment.passed[2].size(), 3u);  // began, lifted, the lift
  EXPECT_EQ(segment.world[2], 1);
  const auto replay = replay_engine(segment);
  for (int k = 0; k < segment.frames(); ++k) {
    ASSERT_TRUE(replay->step());
  }
  EXPECT_EQ(replay->mesh().tet_count(), engine.mesh().tet_count());
  ASSERT_EQ(replay->positions().size(), engine.positions().size());
  for (std::size_t i = 0; i < engine.positions().size(); ++i) {
    ASSERT_EQ(replay->positions()[i], engine.positions()[i]) << "vertex " << i;
  }
}

TEST(SessionRecording, ABadFileNamesItsLine) {
  const auto dir = test::scratch_dir("bad-session");
  const auto expect_error = [&](const std::string& text, const std::string& line) {
    std::ofstream(dir / "s.jsonl") << text;
    try {
      (void)read_session(dir / "s.jsonl");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const InputError& error) {
      EXPECT_NE(std::string(error.what()).find("s.jsonl:" + line), std::string::npos)
          << error.what();
    }
  };
  expect_error("{\"something\": 1}\n", "1");
  const std::string start =
      "{\"incise_session\": 1}\n{\"frame\": 0, \"start\": {\"scene\": \"{}\"}}\n";
  expect_error(start + "{\"frame\": 0, \"lift\": true}\n{\"frame\": 2, \"lift\": true}\n", "4");
  expect_error(start + "{\"frame\": 0, \"pose\": [1, 2, 3]}\n", "3");
  expect_error(start + "{\"frame\": 0, \"pose\": [0, 0, 0, 0, 0, 0, 1], \"world\": 1}\n", "3");
  expect_error(start + "not json\n", "3");
  expect_error(start + "{\"frame\": 0, \"lift\": true, \"through\": [[0, 1]]}\n", "3");
  expect_error(start + "{\"frame\": 0, \"lift\": true, \"through\": 5}\n", "3");
  expect_error("{\"incise_session\": 1}\n{\"frame\": 0, \"lift\": true}\n", "2");
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(FrameSceneOfAVisualSurface, DrawsTheEmbeddedSurfaceOnEveryThread) {
  Engine engine(load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "xfem_skin.json"));
  engine.publish_snapshots(true);
  // Stepped until the visual surface shows the wound, not further: ThreadSanitizer runs this
  // test 50-100 times slower.
  const auto wound_faces = [&engine] {
    const auto surface = engine.visual_surface();
    return surface == nullptr ? 0 : std::count(surface->on_cut.begin(), surface->on_cut.end(), 1);
  };
  while (wound_faces() == 0) {
    ASSERT_LT(engine.frame(), 80) << "the blade has crossed half the patch and cut no face";
    ASSERT_TRUE(engine.step()) << engine.divergence();
  }
  ASSERT_NE(engine.visual(), nullptr);
  const FrameScene here = frame_scene(engine);
  EXPECT_EQ(here.surface, engine.visual_surface());
  EXPECT_EQ(here.surface->triangles.size(), engine.visual()->triangles().size());
  ASSERT_EQ(here.positions.size(), engine.visual()->rest_points().size());
  std::size_t cut = 0;
  for (std::uint8_t on : here.surface->on_cut) {
    cut += on;
  }
  EXPECT_GT(cut, 0u);  // the wound's faces, drawn with the cut texture
  // A copy of the scene keeps its positions (they are shared, not borrowed).
  const FrameScene copy = here;
  EXPECT_EQ(copy.positions.data(), here.positions.data());
  // Another thread's view of the same frame draws the same surface at the same places.
  const FrameScene there = frame_scene(engine.snapshots().latest());
  ASSERT_EQ(there.surface->triangles.size(), here.surface->triangles.size());
  ASSERT_EQ(there.positions.size(), here.positions.size());
  for (std::size_t i = 0; i < here.positions.size(); ++i) {
    ASSERT_EQ(there.positions[i], here.positions[i]) << "point " << i;
  }
  EXPECT_EQ(there.input().triangles.size(), here.input().triangles.size());
}

}  // namespace
}  // namespace incise
