#include "incise/mesh/quality.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace incise {

double min_dihedral_angle(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const std::array<Vec3, 4> p{a, b, c, d};
  // Outward normals of the faces opposite each vertex.
  std::array<Vec3, 4> normals;
  for (int f = 0; f < 4; ++f) {
    const auto& face = tet_local::kFaces[f];
    normals[f] = (p[face[1]] - p[face[0]]).cross(p[face[2]] - p[face[0]]);
    const double length = normals[f].norm();
    if (length == 0.0) {
      return 0.0;
    }
    normals[f] /= length;
  }
  double smallest = std::numbers::pi;
  // The dihedral angle at the edge shared by faces i and j is pi - angle(n_i, n_j).
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      const double cosine = std::clamp(normals[i].dot(normals[j]), -1.0, 1.0);
      smallest = std::min(smallest, std::numbers::pi - std::acos(cosine));
    }
  }
  return smallest;
}

double aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 u = b - a;
  const Vec3 v = c - a;
  const Vec3 w = d - a;
  const double six_volume = std::abs(u.dot(v.cross(w)));
  if (six_volume == 0.0) {
    return std::numeric_limits<double>::infinity();
  }
  const double area_sum = 0.5 * ((c - b).cross(d - b).norm() + v.cross(w).norm() +
                                 u.cross(w).norm() + u.cross(v).norm());
  const double inradius = 0.5 * six_volume / area_sum;  // 3 V / A
  // Circumradius: |u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v), over 2 * 6V.
  const Vec3 numerator =
      u.squaredNorm() * v.cross(w) + v.squaredNorm() * w.cross(u) + w.squaredNorm() * u.cross(v);
  const double circumradius = numerator.norm() / (2.0 * six_volume);
  return circumradius / (3.0 * inradius);
}

QualitySummary summarize_quality(const TetMesh& mesh) {
  QualitySummary summary;
  summary.min_dihedral_histogram.assign(8, 0);
  if (mesh.tet_count() == 0) {
    return summary;
  }
  summary.min_dihedral_deg = std::numeric_limits<double>::infinity();
  double angle_sum = 0.0;
  double aspect_sum = 0.0;
  for (const Tet& tet : mesh.tets()) {
    const Vec3& a = mesh.rest_position(tet[0]);
    const Vec3& b = mesh.rest_position(tet[1]);
    const Vec3& c = mesh.rest_position(tet[2]);
    const Vec3& d = mesh.rest_position(tet[3]);
    const double angle = min_dihedral_angle(a, b, c, d) * 180.0 / std::numbers::pi;
    const double aspect = aspect_ratio(a, b, c, d);
    summary.min_dihedral_deg = std::min(summary.min_dihedral_deg, angle);
    summary.max_dihedral_deg = std::max(summary.max_dihedral_deg, angle);
    summary.max_aspect_ratio = std::max(summary.max_aspect_ratio, aspect);
    angle_sum += angle;
    aspect_sum += aspect;
    const auto bin = static_cast<std::size_t>(std::clamp(angle / 10.0, 0.0, 7.0));
    ++summary.min_dihedral_histogram[bin];
  }
  summary.mean_min_dihedral_deg = angle_sum / static_cast<double>(mesh.tet_count());
  summary.mean_aspect_ratio = aspect_sum / static_cast<double>(mesh.tet_count());
  return summary;
}

}  // namespace incise
