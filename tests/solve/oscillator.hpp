#pragma once
// A single damped spring-mass along x (m x'' + c x' + k x = 0) as a DynamicSystem, with its
// exact solution: the analytical reference for the integrator tests.

#include <cmath>
#include <vector>

#include "incise/physics/dynamic_system.hpp"

namespace incise::test {

class DampedOscillator final : public DynamicSystem {
 public:
  DampedOscillator(double mass, double stiffness, double damping)
      : mass_{mass}, stiffness_(stiffness), damping_(damping) {}

  [[nodiscard]] std::size_t vertex_count() const override { return 1; }
  [[nodiscard]] std::span<const double> masses() const override { return mass_; }
  void forces(double, std::span<const Vec3> x, std::span<const Vec3> v,
              std::span<Vec3> f) override {
    f[0] = -stiffness_ * x[0] - damping_ * v[0];
  }
  Vec3 vertex_force(double, VertexId, const Vec3& x, const Vec3& v, const NeighborState&) override {
    return -stiffness_ * x - damping_ * v;
  }
  [[nodiscard]] std::span<const VertexId> neighbors(VertexId) const override { return {}; }
  [[nodiscard]] bool is_constrained(VertexId) const override { return false; }
  void prescribed_state(double, VertexId, Vec3&, Vec3&) const override {}
  void prepare_linearization(double, std::span<const Vec3>, std::span<const Vec3>) override {}
  void add_linearized_product(double a, double b, std::span<const Vec3> p,
                              std::span<Vec3> y) const override {
    y[0] += (a * stiffness_ + b * damping_) * p[0];
  }
  void add_linearized_diagonal(double a, double b, std::span<Mat3> d) const override {
    d[0] += (a * stiffness_ + b * damping_) * Mat3::Identity();
  }
  [[nodiscard]] double potential_energy(double, std::span<const Vec3> x) const override {
    return 0.5 * stiffness_ * x[0].squaredNorm();
  }
  [[nodiscard]] double max_frequency() const override { return std::sqrt(stiffness_ / mass_[0]); }

  /// Exact x(t) for x(0) = x0, v(0) = 0 (underdamped).
  [[nodiscard]] double exact(double t, double x0) const {
    const double omega = std::sqrt(stiffness_ / mass_[0]);
    const double zeta = damping_ / (2.0 * std::sqrt(stiffness_ * mass_[0]));
    const double omega_d = omega * std::sqrt(1.0 - zeta * zeta);
    return x0 * std::exp(-zeta * omega * t) *
           (std::cos(omega_d * t) + zeta * omega / omega_d * std::sin(omega_d * t));
  }

 private:
  std::vector<double> mass_;
  double stiffness_;
  double damping_;
};

}  // namespace incise::test
