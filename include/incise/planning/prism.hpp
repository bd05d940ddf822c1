#pragma once
// The prismatic volume element of the layered soft-tissue model (Teschner et al.): a bottom
// triangle (p0, p1, p2) on one layer, the top triangle (p3, p4, p5) above it on the next
// (p3 above p0, and so on), and three side faces that are the ruled (bilinear) patches
// between corresponding edges. Pure functions of the six positions.
//
// Volume, exactly: with X(u, v, w) = (1 - w) B(u, v) + w T(u, v) over the unit prism, det dX
// is linear in (u, v) and quadratic in w, and X_w at the triangle's centroid is d, the vector
// from the bottom centroid to the top one, so
//     V = d . (N0 + 4 Nm + N1) / 12
// with N0, Nm, N1 the doubled area vectors (q - p) x (r - p) of the bottom, mid-height and top
// triangles (Simpson's rule, exact for the quadratic). Neighbouring prisms share their side
// patches, so the volumes of a layer sum exactly to the volume it encloses.

#include <Eigen/Core>
#include <array>

#include "incise/core/types.hpp"

namespace incise::planning {

using PrismPoints = std::array<Vec3, 6>;

/// Signed volume (m^3): positive when the top lies on the side of the bottom triangle's normal
/// (p1 - p0) x (p2 - p0).
[[nodiscard]] double prism_volume(const PrismPoints& p);

/// dV/dp_i for the six points (m^2).
[[nodiscard]] std::array<Vec3, 6> prism_volume_gradient(const PrismPoints& p);

using PrismHessian = Eigen::Matrix<double, 18, 18>;
/// d^2 V / dp dp (m), rows and columns ordered p0.x, p0.y, p0.z, p1.x, ... The volume is cubic
/// in the positions, so its gradient is quadratic and central differences of the gradient are
/// exact (up to rounding) for any step: they are taken at the prism's own size.
[[nodiscard]] PrismHessian prism_volume_hessian(const PrismPoints& p);

/// A symmetric 18 x 18 matrix over a prism's corners as its 21 3x3 blocks (a, b) with a <= b,
/// row by row: (0,0), (0,1), ..., (0,5), (1,1), ..., (5,5); block (b, a) is (a, b)^T.
using PrismBlocks = std::array<Mat3, 21>;
/// The place of block (a, b), a <= b, in PrismBlocks.
[[nodiscard]] constexpr std::size_t prism_block(std::size_t a, std::size_t b) {
  return a * 6 - a * (a - 1) / 2 + (b - a);
}
/// prism_volume_hessian's blocks (a, b) with a <= b (m), scaled by `scale` and added to
/// `blocks`.
void add_prism_volume_hessian(const PrismPoints& p, double scale, PrismBlocks& blocks);

}  // namespace incise::planning
