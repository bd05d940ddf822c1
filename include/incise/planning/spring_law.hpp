#pragma once
// The stress-strain law of a spring of the layered tissue model. With strain
// e = (l - l0) / l0, stiffness k (N/m) and nonlinearity a (dimensionless, >= 0):
//     energy  E(l)  = k l0^2 (e^2 / 2 + a e^4 / 4)      (J)
//     tension E'(l) = k l0 (e + a e^3)                  (N)
//     E''(l)        = k (1 + 3 a e^2)                   (N/m)
// a = 0 is Hooke's law; a > 0 stiffens with strain in tension and compression alike, the
// exponential-like rise of soft tissue's stress-strain curve (Fung) to third order.

namespace incise::planning {

/// A spring's law: tension k l0 (e + a e^3) at strain e = (l - l0) / l0 (lengths in m,
/// stiffness k in N/m).
struct SpringLaw {
  double nonlinearity = 0.0;  ///< a

  /// Stored energy (J).
  [[nodiscard]] double energy(double length, double rest, double stiffness) const {
    const double e = (length - rest) / rest;
    return stiffness * rest * rest * (0.5 * e * e + 0.25 * nonlinearity * e * e * e * e);
  }
  /// Tension (N), positive when stretched.
  [[nodiscard]] double tension(double length, double rest, double stiffness) const {
    const double e = (length - rest) / rest;
    return stiffness * rest * (e + nonlinearity * e * e * e);
  }
  /// d tension / d length (N/m).
  [[nodiscard]] double tension_derivative(double length, double rest, double stiffness) const {
    const double e = (length - rest) / rest;
    return stiffness * (1.0 + 3.0 * nonlinearity * e * e);
  }
  /// d tension / d rest length at fixed length (N/m), for the equilibrium initialisation.
  [[nodiscard]] double tension_by_rest(double length, double rest, double stiffness) const {
    const double e = (length - rest) / rest;
    return stiffness * (e + nonlinearity * e * e * e) -
           stiffness * (length / rest) * (1.0 + 3.0 * nonlinearity * e * e);
  }
};

}  // namespace incise::planning
