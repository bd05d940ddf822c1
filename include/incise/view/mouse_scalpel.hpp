#pragma once
// The scalpel in the user's hand: a press picks a point on the body's surface; while the
// button is held the blade follows the cursor on the plane through that point facing the
// camera, reaching `depth` into the body; scrolling changes the depth. Pure geometry, and a
// tool-pose source that hands the blade from the scene's own path to the mouse.

#include <atomic>
#include <memory>
#include <optional>
#include <span>

#include "incise/engine/tool_pose_source.hpp"
#include "incise/render/camera.hpp"

namespace incise {

/// A ray from the eye into the scene.
struct Ray {
  Vec3 origin;     ///< m
  Vec3 direction;  ///< unit
};

/// The ray from the eye through a point of the picture, in normalised device coordinates
/// (x right, y up, both in [-1, 1]).
[[nodiscard]] Ray cursor_ray(const Camera& camera, double aspect, double x, double y);

/// Where a ray meets a surface.
struct SurfaceHit {
  Vec3 point;                ///< m
  std::size_t triangle = 0;  ///< the triangle met
  double distance = 0.0;     ///< along the ray (m)
};

/// The nearest triangle the ray meets (either side), if any.
[[nodiscard]] std::optional<SurfaceHit> pick_surface(const Ray& ray,
                                                     std::span<const Triangle> triangles,
                                                     std::span<const Vec3> positions);

/// Where the cursor's ray crosses the plane through `anchor` facing the camera: the point a
/// drag that started at `anchor` has reached (a picked bone segment follows it). Pure.
[[nodiscard]] Vec3 point_on_anchor_plane(const Camera& camera, const Ray& cursor,
                                         const Vec3& anchor);

/// A turn by the mouse: the angle (radians, counter-clockwise as seen from the camera) that
/// the cursor has swept about `centre` on the screen, from the ray `from` (where the drag
/// started) to the ray `to`; the turn is about the axis from `centre` towards the camera. Zero
/// while either ray passes through the centre. Pure.
[[nodiscard]] double turn_on_screen(const Camera& camera, const Vec3& centre, const Ray& from,
                                    const Ray& to);

/// The axis a turn on the screen is about: from the target towards the camera (unit).
[[nodiscard]] Vec3 towards_camera(const Camera& camera);

/// The blade for a cursor ray, with the stroke anchored at `anchor` (the picked point): it
/// crosses the plane through the anchor facing the camera where the ray does, leaning away
/// from the viewer along the ray and a little down the screen so it is seen as a line; the
/// tip `depth` past the plane, the base `handle` before it (m).
[[nodiscard]] BladePose scalpel_pose(const Camera& camera, const Ray& cursor, const Vec3& anchor,
                                     double depth, double handle);

/// The scene's own tool path until the user takes the blade; from then on the live pose
/// (lifted until the first press). take() and live() may be called from any thread.
class HandOverTool final : public ToolPoseSource {
 public:
  /// Plays `scripted` (may be null: no path) until take().
  explicit HandOverTool(std::unique_ptr<ToolPoseSource> scripted)
      : scripted_(std::move(scripted)) {}
  void take() { taken_.store(true); }  ///< the user takes the blade (any thread)
  [[nodiscard]] bool taken() const { return taken_.load(); }  ///< whether it was taken
  /// The live pose the user sets once the blade is taken.
  [[nodiscard]] LiveToolPose& live() { return live_; }
  [[nodiscard]] std::optional<BladePose> pose(int frame, double time) override {
    if (taken_.load()) {
      last_frame_ = PoseFrame::kWorld;
      return live_.pose(frame, time);
    }
    last_frame_ = PoseFrame::kRest;
    return scripted_ ? scripted_->pose(frame, time) : std::nullopt;
  }
  [[nodiscard]] ToolMotion motion(int frame, double time) override {
    if (taken_.load()) {
      last_frame_ = PoseFrame::kWorld;
      return live_.motion(frame, time);  // with a stroke made between two frames
    }
    return ToolPoseSource::motion(frame, time);
  }
  /// The scene's path is in the rest frame; the mouse works on the picture, in the world.
  [[nodiscard]] PoseFrame frame() const override { return last_frame_; }

 private:
  std::unique_ptr<ToolPoseSource> scripted_;
  LiveToolPose live_{PoseFrame::kWorld};
  std::atomic<bool> taken_{false};           ///< set by the viewer, read by the engine's thread
  PoseFrame last_frame_ = PoseFrame::kRest;  ///< the engine's thread only
};

}  // namespace incise
