#include "incise/engine/pose_frames.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <limits>
#include <vector>

namespace incise {

namespace {

/// Samples along the blade, tip to base: enough that a blade crossing a thin body has one
/// inside it (11 samples: 10 % of the blade between them).
constexpr int kSamples = 11;

std::array<Vec3, 4> corners(std::span<const Vec3> x, const Tet& tet) {
  return {x[static_cast<std::size_t>(tet[0])], x[static_cast<std::size_t>(tet[1])],
          x[static_cast<std::size_t>(tet[2])], x[static_cast<std::size_t>(tet[3])]};
}

Mat3 edges(const std::array<Vec3, 4>& c) {
  Mat3 m;
  m.col(0) = c[1] - c[0];
  m.col(1) = c[2] - c[0];
  m.col(2) = c[3] - c[0];
  return m;
}

/// Whether p lies in the tetrahedron (barycentric coordinates above -tolerance; false for a
/// flat one, whose coordinates are not finite).
bool contains(const std::array<Vec3, 4>& c, const Vec3& p) {
  const auto w = barycentric_coordinates(p, c[0], c[1], c[2], c[3]);
  constexpr double kTolerance = 1e-9;
  return std::all_of(w.begin(), w.end(), [](double b) { return b >= -kTolerance; });
}

double distance_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 d = b - a;
  const double length2 = d.squaredNorm();
  const double t = length2 > 0.0 ? std::clamp((p - a).dot(d) / length2, 0.0, 1.0) : 0.0;
  return (p - (a + t * d)).norm();
}

}  // namespace

std::optional<RestMap> element_map(const TetMesh& mesh, std::span<const Vec3> from,
                                   std::span<const Vec3> to, TetId tet) {
  const Tet& t = mesh.tet(tet);
  const std::array<Vec3, 4> now = corners(from, t);
  const std::array<Vec3, 4> rest = corners(to, t);
  const Mat3 current = edges(now);
  const Mat3 original = edges(rest);
  const double scale = (now[1] - now[0]).squaredNorm() + (now[2] - now[0]).squaredNorm() +
                       (now[3] - now[0]).squaredNorm();
  const double rest_scale = (rest[1] - rest[0]).squaredNorm() + (rest[2] - rest[0]).squaredNorm() +
                            (rest[3] - rest[0]).squaredNorm();
  // Flat (relative volume below 1e-9) in either configuration: no map.
  if (!(std::abs(current.determinant()) > 1e-9 * std::pow(scale, 1.5)) ||
      !(std::abs(original.determinant()) > 1e-9 * std::pow(rest_scale, 1.5))) {
    return std::nullopt;
  }
  RestMap map;
  map.linear = original * current.inverse();
  map.offset = rest[0] - map.linear * now[0];
  return map;
}

std::optional<RestMap> blade_map(const TetMesh& mesh, std::span<const Vec3> x,
                                 std::span<const Vec3> to, const BladePose& world) {
  std::array<Vec3, kSamples> samples;
  Vec3 low = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 high = -low;
  for (int k = 0; k < kSamples; ++k) {
    const double s = static_cast<double>(k) / (kSamples - 1);
    samples[static_cast<std::size_t>(k)] = (1.0 - s) * world.tip + s * world.base;
    low = low.cwiseMin(samples[static_cast<std::size_t>(k)]);
    high = high.cwiseMax(samples[static_cast<std::size_t>(k)]);
  }
  // The element holding each sample, among those whose current box meets the blade's.
  std::array<TetId, kSamples> holder;
  holder.fill(kInvalidId);
  TetId nearest = kInvalidId;
  double nearest_distance = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto id = static_cast<TetId>(t);
    const std::array<Vec3, 4> c = corners(x, mesh.tet(id));
    const Vec3 box_low = c[0].cwiseMin(c[1]).cwiseMin(c[2]).cwiseMin(c[3]);
    const Vec3 box_high = c[0].cwiseMax(c[1]).cwiseMax(c[2]).cwiseMax(c[3]);
    if ((box_high.array() >= low.array()).all() && (box_low.array() <= high.array()).all()) {
      for (std::size_t k = 0; k < samples.size(); ++k) {
        if (holder[k] == kInvalidId && contains(c, samples[k]) && element_map(mesh, x, to, id)) {
          holder[k] = id;
        }
      }
    }
    const double distance =
        distance_to_segment(0.25 * (c[0] + c[1] + c[2] + c[3]), world.tip, world.base);
    if (distance < nearest_distance && element_map(mesh, x, to, id)) {
      nearest_distance = distance;
      nearest = id;
    }
  }
  std::vector<TetId> inside;
  for (TetId id : holder) {
    if (id != kInvalidId) {
      inside.push_back(id);
    }
  }
  const TetId chosen = inside.empty() ? nearest : inside[inside.size() / 2];
  if (chosen == kInvalidId) {
    return std::nullopt;
  }
  return element_map(mesh, x, to, chosen);
}

std::optional<RestMap> blade_rest_map(const TetMesh& mesh, std::span<const Vec3> x,
                                      const BladePose& world) {
  return blade_map(mesh, x, mesh.rest_positions(), world);
}

BladePose mapped(const BladePose& pose, const RestMap& map) {
  return BladePose{pose.time, map(pose.tip), map(pose.base)};
}

}  // namespace incise
