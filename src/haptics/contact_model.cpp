#include "incise/haptics/contact_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "incise/core/error.hpp"
#include "incise/mesh/predicates.hpp"

namespace incise {
namespace {

/// Where the segment [tip, base] crosses the triangle's plane inside the triangle, as a
/// fraction from tip (0) to base (1); floating point is enough for a force model.
std::optional<double> crossing(const Vec3& tip, const Vec3& base, const Vec3& a, const Vec3& b,
                               const Vec3& c) {
  const Vec3 direction = base - tip;
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 p = direction.cross(ac);
  const double determinant = ab.dot(p);
  if (std::abs(determinant) < 1e-30) {
    return std::nullopt;
  }
  const Vec3 t = tip - a;
  const double u = t.dot(p) / determinant;
  if (u < 0.0 || u > 1.0) {
    return std::nullopt;
  }
  const Vec3 q = t.cross(ab);
  const double v = direction.dot(q) / determinant;
  if (v < 0.0 || u + v > 1.0) {
    return std::nullopt;
  }
  const double s = ac.dot(q) / determinant;
  if (s < 0.0 || s > 1.0) {
    return std::nullopt;
  }
  return s;
}

}  // namespace

SurfacePoint nearest_surface_point(std::span<const Triangle> triangles,
                                   std::span<const std::uint8_t> on_cut,
                                   std::span<const Vec3> positions, const Vec3& point) {
  SurfacePoint best;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (on_cut[i] != 0) {
      continue;
    }
    const Triangle& t = triangles[i];
    const double d2 =
        squared_distance_to_triangle(point, positions[t[0]], positions[t[1]], positions[t[2]]);
    if (d2 < nearest) {
      nearest = d2;
      best.triangle = i;
    }
  }
  if (best.triangle < triangles.size()) {
    const Triangle& t = triangles[best.triangle];
    best.barycentric =
        closest_point_barycentric(point, positions[t[0]], positions[t[1]], positions[t[2]]);
  }
  return best;
}

ContactModel build_contact_model(std::span<const Triangle> triangles,
                                 std::span<const std::uint8_t> on_cut,
                                 std::span<const Vec3> positions, const BladePose& blade,
                                 const Material& material, const HapticSpec& haptics, int frame) {
  INCISE_ASSERT(on_cut.size() == triangles.size(), "one cut mark per surface triangle");
  ContactModel model;
  model.frame = frame;
  model.toughness = haptics.cutting_toughness;
  model.advance_speed = haptics.advance_speed;

  // The touched triangle: where the blade enters the exterior surface (the crossing nearest
  // the base, the handle's side), else the exterior triangle nearest the tip.
  std::size_t touched = triangles.size();
  double best_entry = -1.0;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (on_cut[i] != 0) {
      continue;
    }
    const Triangle& t = triangles[i];
    if (const auto s =
            crossing(blade.tip, blade.base, positions[t[0]], positions[t[1]], positions[t[2]]);
        s && *s > best_entry) {
      best_entry = *s;
      touched = i;
    }
  }
  if (touched == triangles.size()) {
    touched = std::min(nearest_surface_point(triangles, on_cut, positions, blade.tip).triangle,
                       triangles.size());
  }
  if (touched == triangles.size()) {
    return model;  // no exterior surface at all
  }

  const Triangle& t = triangles[touched];
  const Vec3& a = positions[t[0]];
  const Vec3& b = positions[t[1]];
  const Vec3& c = positions[t[2]];
  const Vec3 face_normal = (b - a).cross(c - a);
  if (!(face_normal.norm() > 0.0) || !face_normal.allFinite()) {
    return model;
  }
  const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  model.radius = std::max(2.0 * longest, 1e-3);
  const Vec3 unit_face_normal = face_normal.normalized();
  model.anchor = best_entry >= 0.0
                     ? Vec3(blade.tip + best_entry * (blade.base - blade.tip))
                     : Vec3(blade.tip - unit_face_normal.dot(blade.tip - a) * unit_face_normal);

  // The region's normal: area-weighted over the exterior faces within the radius, so a blade
  // on an edge of the mesh feels the surface there, not one facet's tilt.
  Vec3 normal = Vec3::Zero();
  const double radius2 = model.radius * model.radius;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (on_cut[i] != 0) {
      continue;
    }
    const Triangle& f = triangles[i];
    const Vec3 centroid = (positions[f[0]] + positions[f[1]] + positions[f[2]]) / 3.0;
    if ((centroid - model.anchor).squaredNorm() <= radius2) {
      normal += (positions[f[1]] - positions[f[0]]).cross(positions[f[2]] - positions[f[0]]);
    }
  }
  model.normal = normal.norm() > 1e-6 * face_normal.norm() ? normal.normalized() : unit_face_normal;
  model.has_surface = true;
  // The anchor's place in its triangle (the nearest point of it), for the reaction.
  model.triangle = touched;
  model.barycentric = closest_point_barycentric(model.anchor, a, b, c);

  // A rigid flat punch of radius a on an elastic half-space: k = 2 a E / (1 - nu^2)
  // (Boussinesq); the punch is half the region, and desktop devices render only so much.
  const double punch = 0.5 * model.radius;
  const double from_material = 2.0 * punch * material.young_modulus /
                               (1.0 - material.poisson_ratio * material.poisson_ratio);
  model.stiffness = haptics.contact_stiffness > 0.0 ? haptics.contact_stiffness : from_material;
  model.stiffness = std::min(model.stiffness, haptics.contact_stiffness_limit);
  return model;
}

ForceSample evaluate_force(const ContactModel& model, const BladePose& pose,
                           const Vec3& tip_velocity) {
  ForceSample sample;
  if (!model.has_surface || !pose.tip.allFinite() || !pose.base.allFinite()) {
    return sample;
  }
  const double tip_height = model.normal.dot(pose.tip - model.anchor);
  const double base_height = model.normal.dot(pose.base - model.anchor);
  if (tip_height >= 0.0) {
    return sample;  // the tip is above the surface: out of contact
  }
  // Trust the plane near where it was built: full weight within the radius of the point the
  // blade crosses it, none beyond twice that, linear between (continuous in the pose).
  const Vec3 blade = pose.base - pose.tip;
  const double blade_length = blade.norm();
  Vec3 entry = pose.tip;
  if (base_height > 0.0) {
    entry = pose.tip + (-tip_height / (base_height - tip_height)) * blade;
  }
  const Vec3 lateral = entry - model.anchor - model.normal.dot(entry - model.anchor) * model.normal;
  const double weight = std::clamp(2.0 - lateral.norm() / model.radius, 0.0, 1.0);
  if (weight == 0.0) {
    return sample;
  }
  sample.depth = -tip_height;
  sample.contact = weight * model.stiffness * sample.depth * model.normal;

  // Cutting: the blade below the surface opens tissue as it moves across its own axis.
  const double below = base_height > 0.0 ? -tip_height / (base_height - tip_height) : 1.0;
  sample.wetted_length = below * blade_length;
  if (blade_length > 0.0 && model.toughness > 0.0) {
    const Vec3 axis = blade / blade_length;
    const Vec3 advance = tip_velocity - tip_velocity.dot(axis) * axis;
    const double speed = advance.norm();
    if (speed > 0.0 && std::isfinite(speed)) {
      sample.cutting = -weight * model.toughness * sample.wetted_length * advance /
                       std::max(speed, model.advance_speed);
    }
  }
  return sample;
}

ForceFilter::ForceFilter(double limit, double max_step) : limit_(limit), max_step_(max_step) {
  INCISE_ASSERT(limit > 0.0 && max_step > 0.0, "force limits must be positive");
}

Vec3 ForceFilter::apply(const Vec3& wanted) {
  Vec3 target = wanted.allFinite() ? wanted : Vec3::Zero();
  const double magnitude = target.norm();
  if (magnitude > limit_) {
    target *= limit_ / magnitude;
  }
  // Both ends lie in the ball of radius limit, so every point between them does too.
  const Vec3 step = target - last_;
  const double step_length = step.norm();
  last_ += step_length > max_step_ ? Vec3(step * (max_step_ / step_length)) : step;
  return last_;
}

VelocityEstimator::VelocityEstimator(double window) : window_(window) {}

void VelocityEstimator::add(double time, const Vec3& tip) {
  if (count_ > 0) {
    const Sample& newest = ring_[(next_ + ring_.size() - 1) % ring_.size()];
    if (time < newest.time) {
      reset();  // a clock that went back: start afresh rather than differentiate across it
    }
  }
  ring_[next_] = {time, tip};
  next_ = (next_ + 1) % ring_.size();
  count_ = std::min(count_ + 1, ring_.size());
}

Vec3 VelocityEstimator::velocity() const {
  if (count_ < 2) {
    return Vec3::Zero();
  }
  const Sample& newest = ring_[(next_ + ring_.size() - 1) % ring_.size()];
  // The oldest sample still inside the window (at least the one before the newest).
  const Sample* oldest = &ring_[(next_ + ring_.size() - 2) % ring_.size()];
  for (std::size_t back = 2; back <= count_; ++back) {
    const Sample& candidate = ring_[(next_ + ring_.size() - back) % ring_.size()];
    if (newest.time - candidate.time > window_) {
      break;
    }
    oldest = &candidate;
  }
  const double dt = newest.time - oldest->time;
  return dt > 0.0 ? Vec3((newest.tip - oldest->tip) / dt) : Vec3::Zero();
}

void VelocityEstimator::reset() {
  count_ = 0;
  next_ = 0;
}

}  // namespace incise
