#pragma once
// Solid (3-D) tissue textures, looked up at rest-space coordinates: a face a cut opens shows
// the tissue that was there at rest, wherever and however often the body is cut, and a face
// keeps its texture while the body deforms (texture coordinates never need to be made up for
// new faces; cf. SOFA issue #2392, texture coordinates lost after topological changes).

#include <array>
#include <cstdint>
#include <vector>

namespace incise {

enum class TissueLook : std::uint8_t {
  kExterior,  ///< the organ's outside: a pale, mottled capsule with faint vessels
  kCut,       ///< the inside a cut shows: deep red parenchyma with fibres
};

/// size^3 RGB texels, x fastest; it tiles seamlessly in every direction.
struct SolidTexture {
  int size = 0;                                     ///< texels per side
  std::vector<std::array<std::uint8_t, 3>> texels;  ///< size^3, x fastest
  /// The texel at (i, j, k), each in [0, size).
  [[nodiscard]] const std::array<std::uint8_t, 3>& at(int i, int j, int k) const {
    return texels[(static_cast<std::size_t>(k) * static_cast<std::size_t>(size) +
                   static_cast<std::size_t>(j)) *
                      static_cast<std::size_t>(size) +
                  static_cast<std::size_t>(i)];
  }
};

/// A procedural texture (periodic value noise, a few octaves), the same for the same seed.
[[nodiscard]] SolidTexture make_tissue_texture(TissueLook look, int size = 64,
                                               std::uint32_t seed = 1);

}  // namespace incise
