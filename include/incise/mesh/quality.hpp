#pragma once
// Element quality measures, pure functions of the four vertex positions.

#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// Smallest of the six dihedral angles (radians); about 1.2310 (70.53 deg) when regular.
[[nodiscard]] double min_dihedral_angle(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
/// Aspect ratio R / (3 r) (circumradius over three inradii): 1 when regular, grows without
/// bound as the tetrahedron flattens; +inf for a flat one.
[[nodiscard]] double aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Element quality over a mesh: dihedral angles (degrees) and aspect ratios (1: regular).
struct QualitySummary {
  double min_dihedral_deg = 0.0;       ///< the smallest dihedral angle of any tetrahedron
  double max_dihedral_deg = 0.0;       ///< the largest of the per-tet minimum angles
  double mean_min_dihedral_deg = 0.0;  ///< the per-tet minimum angles' mean
  double max_aspect_ratio = 0.0;       ///< the worst tetrahedron's
  double mean_aspect_ratio = 0.0;      ///< over all tetrahedra
  /// Count of tets by minimum dihedral angle in 10-degree bins: [0,10), ..., [60,70), >= 70.
  std::vector<std::size_t> min_dihedral_histogram;
};

[[nodiscard]] QualitySummary summarize_quality(const TetMesh& mesh);

}  // namespace incise
