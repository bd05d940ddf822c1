#include "incise/cut/blade_walk.hpp"

#include <cmath>

namespace incise {

std::vector<BladePose> sweep_along_x(const Vec3& low, const Vec3& high, double y_fraction,
                                     double end_fraction, int poses, double margin, double dt) {
  const Vec3 size = high - low;
  const double y = low.y() + y_fraction * size.y();
  std::vector<BladePose> path;
  for (int i = 0; i <= poses; ++i) {
    const double x = low.x() - margin * size.x() + (end_fraction + margin) * size.x() * i / poses;
    path.push_back({dt * i, Vec3(x, y, low.z() - margin * size.z()),
                    Vec3(x, y, high.z() + margin * size.z())});
  }
  return path;
}

std::vector<BladePose> random_blade_walk(const Vec3& low, const Vec3& high, std::mt19937& rng,
                                         int poses) {
  // Steps and events in coordinates normalised to the box.
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> tremor(0.0, 0.004);
  const Vec3 size = high - low;
  Vec3 at(unit(rng), unit(rng), 0.5);
  double heading = 6.283 * unit(rng);
  double turn = 0.0;
  double tilt = 0.3 * (unit(rng) - 0.5);
  std::vector<BladePose> path;
  for (int i = 0; i < poses; ++i) {
    const double event = unit(rng);
    double step = 0.03;
    if (event < 0.08) {
      heading += 3.14159;  // reversal: saw back
    } else if (event < 0.14) {
      step = 0.0;  // stop
    } else if (event < 0.18) {
      at = Vec3(unit(rng), unit(rng), 0.5);  // lift out and re-enter elsewhere
    } else if (event < 0.3) {
      turn = 0.6 * (unit(rng) - 0.5);  // start a curve
    }
    heading += turn;
    at += Vec3(step * std::cos(heading) + tremor(rng), step * std::sin(heading) + tremor(rng), 0);
    at = at.cwiseMax(Vec3(-0.2, -0.2, 0.0)).cwiseMin(Vec3(1.2, 1.2, 1.0));
    tilt += tremor(rng);
    const Vec3 tip = low + Vec3(at.x() - tilt, at.y(), -0.1).cwiseProduct(size);
    const Vec3 base = low + Vec3(at.x() + tilt, at.y() + 0.5 * tilt, 1.1).cwiseProduct(size);
    path.push_back({0.01 * i, tip, base});
  }
  return path;
}

}  // namespace incise
