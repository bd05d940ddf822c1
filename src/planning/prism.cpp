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

PrismHessian prism_volume_hessian(const PrismPoints& p) {
  double size = 0.0;
  for (std::size_t i = 1; i < 6; ++i) {
    size = std::max(size, (p[i] - p[0]).norm());
  }
  const double h = size > 0.0 ? size : 1.0;
  PrismHessian hessian;
  for (int column = 0; column < 18; ++column) {
    PrismPoints plus = p;
    PrismPoints minus = p;
    plus[static_cast<std::size_t>(column / 3)][column % 3] += h;
    minus[static_cast<std::size_t>(column / 3)][column % 3] -= h;
    const std::array<Vec3, 6> gp = prism_volume_gradient(plus);
    const std::array<Vec3, 6> gm = prism_volume_gradient(minus);
    for (std::size_t i = 0; i < 6; ++i) {
      hessian.block<3, 1>(static_cast<Eigen::Index>(3 * i), column) = (gp[i] - gm[i]) / (2.0 * h);
    }
  }
  return 0.5 * (hessian + hessian.transpose());
}

}  // namespace incise::planning
