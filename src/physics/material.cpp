#include "incise/physics/material.hpp"

#include <cmath>

#include "incise/core/error.hpp"

namespace incise {

void Material::check() const {
  if (!(young_modulus > 0.0) || !std::isfinite(young_modulus)) {
    throw InputError("Young's modulus must be positive (Pa)");
  }
  if (!(poisson_ratio > -1.0 && poisson_ratio < 0.5)) {
    throw InputError("Poisson ratio must lie in (-1, 0.5)");
  }
  if (!(density > 0.0) || !std::isfinite(density)) {
    throw InputError("density must be positive (kg/m^3)");
  }
}

Material material_preset(const std::string& name) {
  // Small-strain, quasi-static values; soft tissue is nearly incompressible (nu 0.45-0.49).
  // Densities: F. A. Duck, Physical Properties of Tissue, Academic Press 1990.
  if (name == "liver") {
    // Shear modulus about 1.8 kPa in healthy liver by MR elastography (M. Yin et al., Clin.
    // Gastroenterol. Hepatol. 5:1207, 2007): E = 2 mu (1 + nu) = 5.3 kPa at nu = 0.47.
    return {2.0 * 1.8e3 * (1.0 + 0.47), 0.47, 1060.0};
  }
  if (name == "skin") {
    // In vivo indentation of human skin gives E of the order of 10 kPa at small strain
    // (C. Pailler-Mattei et al., Med. Eng. Phys. 30:599, 2008); density 1100 kg/m^3.
    return {1.0e4, 0.48, 1100.0};
  }
  if (name == "fat") {
    // Adipose tissue, E about 3.2 kPa (A. Samani, D. Plewes, Phys. Med. Biol. 49:4395, 2004).
    return {3.2e3, 0.49, 920.0};
  }
  if (name == "muscle") {
    // Relaxed skeletal muscle, shear modulus about 4 kPa by shear-wave elastography
    // (J.-L. Gennisson et al., Ultrasound Med. Biol. 36:789, 2010): E = 12 kPa.
    return {1.2e4, 0.49, 1060.0};
  }
  std::string known;
  for (const std::string& preset : material_preset_names()) {
    known += (known.empty() ? "" : ", ") + preset;
  }
  throw InputError("unknown material preset '" + name + "' (known: " + known + ")");
}

std::vector<std::string> material_preset_names() {
  return {"liver", "skin", "fat", "muscle"};
}

}  // namespace incise
