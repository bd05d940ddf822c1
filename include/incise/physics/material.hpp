#pragma once
// Tissue materials with units, and named presets from the literature.

#include <string>
#include <vector>

namespace incise {

/// A linear elastic tissue material in SI units (scene key `material`, or a preset's name).
struct Material {
  double young_modulus = 5.4e3;  ///< Pa
  double poisson_ratio = 0.47;   ///< dimensionless, in (-1, 0.5)
  double density = 1060.0;       ///< kg/m^3

  /// Shear modulus mu = E / (2 (1 + nu)) (Pa).
  [[nodiscard]] double shear_modulus() const {
    return young_modulus / (2.0 * (1.0 + poisson_ratio));
  }
  /// Lame's first parameter lambda = E nu / ((1 + nu)(1 - 2 nu)) (Pa).
  [[nodiscard]] double lame_lambda() const {
    return young_modulus * poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio));
  }
  /// Throws InputError unless E > 0, -1 < nu < 0.5 and density > 0.
  void check() const;
};

/// A named preset ("liver", "skin", "fat", "muscle"); throws InputError for an unknown name,
/// listing the known ones.
[[nodiscard]] Material material_preset(const std::string& name);
/// The presets' names.
[[nodiscard]] std::vector<std::string> material_preset_names();

}  // namespace incise
