#include "incise/view/mouse_scalpel.hpp"

#include <cmath>
#include <limits>
#include <numbers>

namespace incise {

Ray cursor_ray(const Camera& camera, double aspect, double x, double y) {
  const Mat4 view = view_matrix(camera);
  const Vec3 right = view.block<1, 3>(0, 0).transpose();
  const Vec3 up = view.block<1, 3>(1, 0).transpose();
  const Vec3 forward = -view.block<1, 3>(2, 0).transpose();
  const double half = std::tan(0.5 * camera.fov_y_degrees * std::numbers::pi / 180.0);
  const Vec3 direction = forward + x * half * aspect * right + y * half * up;
  return {camera.eye, direction.normalized()};
}

std::optional<SurfaceHit> pick_surface(const Ray& ray, std::span<const Triangle> triangles,
                                       std::span<const Vec3> positions) {
  // Moeller-Trumbore, both sides.
  std::optional<SurfaceHit> best;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Vec3& a = positions[static_cast<std::size_t>(triangles[t][0])];
    const Vec3& b = positions[static_cast<std::size_t>(triangles[t][1])];
    const Vec3& c = positions[static_cast<std::size_t>(triangles[t][2])];
    const Vec3 e1 = b - a;
    const Vec3 e2 = c - a;
    const Vec3 p = ray.direction.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-300) {
      continue;
    }
    const Vec3 s = ray.origin - a;
    const double u = s.dot(p) / det;
    if (u < 0.0 || u > 1.0) {
      continue;
    }
    const Vec3 q = s.cross(e1);
    const double v = ray.direction.dot(q) / det;
    if (v < 0.0 || u + v > 1.0) {
      continue;
    }
    const double distance = e2.dot(q) / det;
    if (distance > 0.0 && (!best || distance < best->distance)) {
      best = SurfaceHit{ray.origin + distance * ray.direction, t, distance};
    }
  }
  return best;
}

Vec3 point_on_anchor_plane(const Camera& camera, const Ray& cursor, const Vec3& anchor) {
  const Vec3 forward = -view_matrix(camera).block<1, 3>(2, 0).transpose();
  const double along = (anchor - cursor.origin).dot(forward) / cursor.direction.dot(forward);
  return cursor.origin + along * cursor.direction;
}

Vec3 towards_camera(const Camera& camera) {
  return view_matrix(camera).block<1, 3>(2, 0).transpose();
}

double turn_on_screen(const Camera& camera, const Vec3& centre, const Ray& from, const Ray& to) {
  const Vec3 axis = towards_camera(camera);
  const Vec3 a = point_on_anchor_plane(camera, from, centre) - centre;
  const Vec3 b = point_on_anchor_plane(camera, to, centre) - centre;
  // A ray through the centre has no direction about it (to rounding, relative to the view).
  const double tiny = 1e-9 * (camera.eye - centre).norm();
  if (a.norm() <= tiny || b.norm() <= tiny) {
    return 0.0;
  }
  return std::atan2(axis.dot(a.cross(b)), a.dot(b));
}

BladePose scalpel_pose(const Camera& camera, const Ray& cursor, const Vec3& anchor, double depth,
                       double handle) {
  const Vec3 up = view_matrix(camera).block<1, 3>(1, 0).transpose();
  const Vec3 point = point_on_anchor_plane(camera, cursor, anchor);
  const Vec3 lean = (cursor.direction - 0.5 * up).normalized();
  BladePose pose;
  pose.tip = point + depth * lean;
  pose.base = point - handle * lean;
  return pose;
}

}  // namespace incise
