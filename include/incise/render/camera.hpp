#pragma once
// A perspective camera: where it stands, what it looks at, and the matrices OpenGL wants.
// Pure functions of their inputs, testable without a GL context.

#include <Eigen/Core>
#include <limits>

#include "incise/core/types.hpp"

namespace incise {

using Mat4 = Eigen::Matrix4d;

/// A perspective camera.
struct Camera {
  Vec3 eye{0.0, -1.0, 0.0};     ///< m
  Vec3 target{0.0, 0.0, 0.0};   ///< m: the point looked at
  Vec3 up{0.0, 0.0, 1.0};       ///< the picture's up direction
  double fov_y_degrees = 35.0;  ///< vertical field of view
};

/// An axis-aligned box (m).
struct Bounds {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::infinity());   ///< low corner
  Vec3 max = Vec3::Constant(-std::numeric_limits<double>::infinity());  ///< high corner
  /// Grows the box to hold p.
  void add(const Vec3& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  /// Whether no point was added.
  [[nodiscard]] bool empty() const { return !(min.array() <= max.array()).all(); }
  /// The box's centre (m).
  [[nodiscard]] Vec3 centre() const { return 0.5 * (min + max); }
  /// Half its diagonal (m): the radius of a sphere around it.
  [[nodiscard]] double radius() const { return 0.5 * (max - min).norm(); }
};

/// A camera looking at the box's centre from `direction` (towards the eye), far enough for
/// the box's bounding sphere to fill `fill` of the shorter side of the picture.
[[nodiscard]] Camera fit_camera(const Bounds& box, double aspect, const Vec3& direction,
                                const Vec3& up = Vec3::UnitZ(), double fill = 0.8);
/// The default view of a body: from the front-right, a little above (z up).
[[nodiscard]] Camera fit_camera(const Bounds& box, double aspect);

/// World to eye coordinates (right-handed, looking down -z).
[[nodiscard]] Mat4 view_matrix(const Camera& camera);
/// Eye to clip coordinates; near and far planes enclose `scene` with a margin.
[[nodiscard]] Mat4 projection_matrix(const Camera& camera, double aspect, const Bounds& scene);

/// Orbits the eye around the target: `yaw` about `up`, `pitch` about the camera's right axis
/// (radians), keeping the distance; pitch stops short of the poles.
void orbit(Camera& camera, double yaw, double pitch);
/// Moves eye and target together in the view plane by fractions of the target distance.
void pan(Camera& camera, double right, double upward);
/// Scales the eye's distance to the target (factor > 0; < 1 comes closer).
void zoom(Camera& camera, double factor);

}  // namespace incise
