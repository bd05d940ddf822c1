#pragma once
// The corotated element maths of corotational.hpp for four tetrahedra at once: deformation
// gradient, polar rotation from a warm start, first Piola-Kirchhoff stress and the rotated
// shape gradients, laid out as a structure of arrays so that one SIMD register holds one
// quantity of four elements. What the FEM model's force pass runs: per element it is the
// largest fixed cost of an implicit step (BENCHMARKS.md, "Element kernels over four
// tetrahedra").
//
// The results equal the one-element functions' up to rounding: the same Newton iteration on
// the rotation, lane by lane; a lane that leaves its fast path (a flat or inverted element, a
// large turn, a non-finite F, slow convergence) is finished by polar_rotation() itself. Lanes
// do not mix, so an element's result does not depend on which lane or batch it was given in.
// Pure: no mesh, no state.

#include "incise/physics/corotational.hpp"

namespace incise {

inline constexpr int kElementLanes = 4;

/// Four elements' inputs and results, indexed [...][lane]. 3x3 matrices are column-major:
/// entry (i, j) at [3 j + i].
struct alignas(64) CorotatedBatch {
  // ---- in
  double corners[4][3][kElementLanes];    ///< corner a's coordinate c (m)
  double gradients[4][3][kElementLanes];  ///< grad N_a in the rest configuration (1/m)
  double mu[kElementLanes];               ///< Lame's mu (Pa)
  double lambda[kElementLanes];           ///< Lame's lambda (Pa)
  double stress_scale[kElementLanes];     ///< what P is multiplied by: -w V (m^3)
  // ---- in and out
  /// The rotation's warm start as a unit quaternion w, x, y, z; the rotation found, out.
  double quaternion[4][kElementLanes];
  // ---- out
  double deformation[9][kElementLanes];           ///< F
  double rotation[9][kElementLanes];              ///< R of F = R S
  double scaled_stress[9][kElementLanes];         ///< stress_scale * P (N m)
  double rotated_gradients[4][3][kElementLanes];  ///< R grad N_a (1/m)
};

/// One lane of a batch's vectors, matrices and quaternions as Eigen values, and the same
/// written: what callers gather elements into a batch and take results out with.
[[nodiscard]] inline Vec3 lane_vector(const double (&entries)[3][kElementLanes], int lane) {
  return {entries[0][lane], entries[1][lane], entries[2][lane]};
}
inline void set_lane_vector(double (&entries)[3][kElementLanes], int lane, const Vec3& value) {
  for (int c = 0; c < 3; ++c) {
    entries[c][lane] = value[c];
  }
}
[[nodiscard]] inline Mat3 lane_matrix(const double (&entries)[9][kElementLanes], int lane) {
  Mat3 matrix;
  for (int k = 0; k < 9; ++k) {
    matrix.data()[k] = entries[k][lane];
  }
  return matrix;
}
inline void set_lane_matrix(double (&entries)[9][kElementLanes], int lane, const Mat3& matrix) {
  for (int k = 0; k < 9; ++k) {
    entries[k][lane] = matrix.data()[k];
  }
}
[[nodiscard]] inline Eigen::Quaterniond lane_quaternion(const CorotatedBatch& batch, int lane) {
  return {batch.quaternion[0][lane], batch.quaternion[1][lane], batch.quaternion[2][lane],
          batch.quaternion[3][lane]};
}
inline void set_lane_quaternion(CorotatedBatch& batch, int lane, const Eigen::Quaterniond& q) {
  batch.quaternion[0][lane] = q.w();
  batch.quaternion[1][lane] = q.x();
  batch.quaternion[2][lane] = q.y();
  batch.quaternion[3][lane] = q.z();
}

/// Fills the results of lanes 0..count-1 (1 <= count <= kElementLanes); the other lanes'
/// inputs are not read for anything that is kept. Uses AVX2 and FMA where the CPU has them.
void corotated_batch(CorotatedBatch& batch, int count);

/// Row a of an element's warped stiffness added to its four blocks: for b = 0..3,
///   *blocks[b] += lambda_a r_b^T + r_b mu_a^T + diagonal[b] I,
/// the sum add_warped_stiffness_block() makes (corotational.hpp), with SIMD across a block's
/// entries where the CPU has AVX2 (assembly runs this 4 times per element).
void add_warped_stiffness_row(const std::array<Mat3*, 4>& blocks, const Vec3& lambda_a,
                              const Vec3& mu_a, const std::array<Vec3, 4>& rotated,
                              const std::array<double, 4>& diagonal);

namespace detail {
/// The same built without AVX2, what a CPU without it runs (so that tests cover both).
void corotated_batch_portable(CorotatedBatch& batch, int count);
void add_warped_stiffness_row_portable(const std::array<Mat3*, 4>& blocks, const Vec3& lambda_a,
                                       const Vec3& mu_a, const std::array<Vec3, 4>& rotated,
                                       const std::array<double, 4>& diagonal);
}  // namespace detail

}  // namespace incise
