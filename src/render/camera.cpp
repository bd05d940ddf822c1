#include "incise/render/camera.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "incise/core/error.hpp"

namespace incise {

namespace {

double radians(double degrees) {
  return degrees * std::numbers::pi / 180.0;
}

}  // namespace

Camera fit_camera(const Bounds& box, double aspect, const Vec3& direction, const Vec3& up,
                  double fill) {
  INCISE_ASSERT(!box.empty() && aspect > 0.0 && fill > 0.0, "fitting a camera to nothing");
  Camera camera;
  camera.up = up;
  camera.target = box.centre();
  const double radius = std::max(box.radius(), 1e-9);
  // The sphere fills `fill` of the narrower field of view.
  const double half_fov_y = 0.5 * radians(camera.fov_y_degrees);
  const double half_fov_x = std::atan(std::tan(half_fov_y) * aspect);
  const double half = std::min(half_fov_y, half_fov_x);
  const double distance = radius / (fill * std::sin(half));
  camera.eye = camera.target + distance * direction.normalized();
  return camera;
}

Camera fit_camera(const Bounds& box, double aspect) {
  return fit_camera(box, aspect, Vec3(0.8, -1.4, 0.9));
}

Mat4 view_matrix(const Camera& camera) {
  const Vec3 forward = (camera.target - camera.eye).normalized();
  Vec3 right = forward.cross(camera.up);
  if (right.norm() < 1e-12) {
    right = forward.unitOrthogonal();  // looking along up: any right will do
  }
  right.normalize();
  const Vec3 true_up = right.cross(forward);
  Mat4 view = Mat4::Identity();
  view.block<1, 3>(0, 0) = right.transpose();
  view.block<1, 3>(1, 0) = true_up.transpose();
  view.block<1, 3>(2, 0) = -forward.transpose();
  view(0, 3) = -right.dot(camera.eye);
  view(1, 3) = -true_up.dot(camera.eye);
  view(2, 3) = forward.dot(camera.eye);
  return view;
}

Mat4 projection_matrix(const Camera& camera, double aspect, const Bounds& scene) {
  const double distance = (camera.eye - scene.centre()).norm();
  const double radius = std::max(scene.radius(), 1e-6);
  const double far_plane = distance + 2.0 * radius;
  const double near_plane = std::max(distance - 2.0 * radius, far_plane * 1e-4);
  const double f = 1.0 / std::tan(0.5 * radians(camera.fov_y_degrees));
  Mat4 projection = Mat4::Zero();
  projection(0, 0) = f / aspect;
  projection(1, 1) = f;
  projection(2, 2) = (far_plane + near_plane) / (near_plane - far_plane);
  projection(2, 3) = 2.0 * far_plane * near_plane / (near_plane - far_plane);
  projection(3, 2) = -1.0;
  return projection;
}

void orbit(Camera& camera, double yaw, double pitch) {
  const Vec3 up = camera.up.normalized();
  Vec3 offset = camera.eye - camera.target;
  offset = Eigen::AngleAxisd(yaw, up) * offset;
  const double distance = offset.norm();
  // Keep at least ~3 degrees from the poles, where the right axis is undefined.
  const double elevation = std::asin(std::clamp(offset.dot(up) / distance, -1.0, 1.0));
  const double limit = 0.5 * std::numbers::pi - 0.05;
  const double new_elevation = std::clamp(elevation + pitch, -limit, limit);
  const Vec3 right = up.cross(offset).normalized();
  offset = Eigen::AngleAxisd(elevation - new_elevation, right) * offset;
  camera.eye = camera.target + offset;
}

void pan(Camera& camera, double right, double upward) {
  const Mat4 view = view_matrix(camera);
  const double distance = (camera.eye - camera.target).norm();
  const Vec3 shift = distance * (right * view.block<1, 3>(0, 0).transpose() +
                                 upward * view.block<1, 3>(1, 0).transpose());
  camera.eye += shift;
  camera.target += shift;
}

void zoom(Camera& camera, double factor) {
  INCISE_ASSERT(factor > 0.0, "zoom factor must be positive");
  camera.eye = camera.target + factor * (camera.eye - camera.target);
}

}  // namespace incise
