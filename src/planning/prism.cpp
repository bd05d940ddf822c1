#include "incise/planning/prism.hpp"

#include <algorithm>

namespace incise::planning {

namespace {

Vec3 doubled_area(const Vec3& p, const Vec3& q, const Vec3& r) {
  return (q - p).cross(r - p);
}

}  // namespace

double prism_volume(const PrismPoints& p) {
  const Vec3 d = (p[3] + p[4] + p[5] - p[0] - p[1] - p[2]) / 3.0;
  const Vec3 m0 = 0.5 * (p[0] + p[3]);
  const Vec3 m1 = 0.5 * (p[1] + p[4]);
  const Vec3 m2 = 0.5 * (p[2] + p[5]);
  const Vec3 sum = doubled_area(p[0], p[1], p[2]) + 4.0 * doubled_area(m0, m1, m2) +
                   doubled_area(p[3], p[4], p[5]);
  return d.dot(sum) / 12.0;
}

std::array<Vec3, 6> prism_volume_gradient(const PrismPoints& p) {
  const Vec3 d = (p[3] + p[4] + p[5] - p[0] - p[1] - p[2]) / 3.0;
  const std::array<Vec3, 3> m = {0.5 * (p[0] + p[3]), 0.5 * (p[1] + p[4]), 0.5 * (p[2] + p[5])};
  const Vec3 sum = doubled_area(p[0], p[1], p[2]) + 4.0 * doubled_area(m[0], m[1], m[2]) +
                   doubled_area(p[3], p[4], p[5]);
  std::array<Vec3, 6> gradient;
  // d depends on every point: -1/3 for the bottom, +1/3 for the top.
  for (int i = 0; i < 3; ++i) {
    gradient[i] = -sum / 3.0;
    gradient[i + 3] = sum / 3.0;
  }
  // d . ((q - p) x (r - p)) has gradient (q - r) x d at p, cyclically.
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const int k = (i + 2) % 3;
    gradient[i] += (p[j] - p[k]).cross(d);
    gradient[i + 3] += (p[j + 3] - p[k + 3]).cross(d);
    // The mid triangle's corner m_i = (p_i + p_{i+3}) / 2, weighted 4.
    const Vec3 mid = 2.0 * (m[j] - m[k]).cross(d);
    gradient[i] += mid;
    gradient[i + 3] += mid;
  }
  for (Vec3& g : gradient) {
    g /= 12.0;
  }
  return gradient;
}

void add_prism_volume_hessian(const PrismPoints& p, double scale, PrismBlocks& blocks) {
  // V = d . S / 12 with d = (top sum - bottom sum) / 3 (linear) and S = N0 + 4 Nm + N1
  // (quadratic), so d^2V/dp_a dp_b = (s_a / 3 dS/dp_b + s_b / 3 (dS/dp_a)^T + d.d^2S) / 12,
  // s = -1 for the bottom, +1 for the top. For N = (q - p) x (r - p): dN/dp = [r - q]x
  // (cyclically), and d.N has the block -[d]x at (p, q), (q, r), (r, p) and its transpose at
  // the mirrored places. A mid-triangle corner m_i = (p_i + p_{i+3}) / 2 takes half of each
  // derivative, and Nm carries the weight 4.
  const Vec3 d = (p[3] + p[4] + p[5] - p[0] - p[1] - p[2]) / 3.0;
  const std::array<Vec3, 3> m = {0.5 * (p[0] + p[3]), 0.5 * (p[1] + p[4]), 0.5 * (p[2] + p[5])};
  const double s = scale / 12.0;
  std::array<Mat3, 6> jacobian;  // dS/dp_a, times scale / 36
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3;
    const std::size_t k = (i + 2) % 3;
    const Mat3 mid = 2.0 * cross_matrix(m[k] - m[j]);
    jacobian[i] = (s / 3.0) * (cross_matrix(p[k] - p[j]) + mid);
    jacobian[i + 3] = (s / 3.0) * (cross_matrix(p[k + 3] - p[j + 3]) + mid);
  }
  for (std::size_t a = 0; a < 6; ++a) {
    const double sa = a < 3 ? -1.0 : 1.0;
    for (std::size_t b = a; b < 6; ++b) {
      const double sb = b < 3 ? -1.0 : 1.0;
      blocks[prism_block(a, b)] += sa * jacobian[b] + sb * jacobian[a].transpose();
    }
  }
  // -[d]x at (a, b) and [d]x at (b, a): -[d]x on the block stored, whichever of the two it is.
  const Mat3 twist = s * cross_matrix(d);
  const auto add = [&](std::size_t a, std::size_t b) {
    if (a < b) {
      blocks[prism_block(a, b)] -= twist;
    } else {
      blocks[prism_block(b, a)] += twist;
    }
  };
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3;
    add(i, j);          // N0
    add(i + 3, j + 3);  // N1
    // 4 Nm: each of the four pairs of corners behind (m_i, m_j) takes 4 / 4 of -[d]x.
    add(i, j);
    add(i, j + 3);
    add(i + 3, j);
    add(i + 3, j + 3);
  }
}

PrismHessian prism_volume_hessian(const PrismPoints& p) {
  PrismBlocks blocks;
  for (Mat3& block : blocks) {
    block.setZero();
  }
  add_prism_volume_hessian(p, 1.0, blocks);
  PrismHessian hessian;
  for (std::size_t a = 0; a < 6; ++a) {
    for (std::size_t b = a; b < 6; ++b) {
      const Mat3& block = blocks[prism_block(a, b)];
      hessian.block<3, 3>(static_cast<Eigen::Index>(3 * a), static_cast<Eigen::Index>(3 * b)) =
          block;
      hessian.block<3, 3>(static_cast<Eigen::Index>(3 * b), static_cast<Eigen::Index>(3 * a)) =
          block.transpose();
    }
  }
  return hessian;
}

}  // namespace incise::planning
