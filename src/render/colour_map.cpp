#include "incise/render/colour_map.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace incise {

namespace {

/// Moreland's diverging map at t = 0, 1/8, ..., 1 (from the table of his paper, "Diverging
/// Color Maps for Scientific Visualization", 2009), linear in between.
constexpr std::array<std::array<int, 3>, 9> kCoolToWarm{{{59, 76, 192},
                                                         {98, 130, 234},
                                                         {141, 176, 254},
                                                         {184, 208, 249},
                                                         {221, 221, 221},
                                                         {245, 196, 173},
                                                         {244, 154, 123},
                                                         {222, 96, 77},
                                                         {180, 4, 38}}};

}  // namespace

Rgba cool_to_warm(double t) {
  if (!(t > 0.0)) {
    t = 0.0;
  }
  t = std::min(t, 1.0);
  const double at = t * static_cast<double>(kCoolToWarm.size() - 1);
  const auto low = std::min(static_cast<std::size_t>(at), kCoolToWarm.size() - 2);
  const double f = at - static_cast<double>(low);
  const auto mix = [&](std::size_t channel) {
    const double value = (1.0 - f) * kCoolToWarm[low][channel] + f * kCoolToWarm[low + 1][channel];
    return static_cast<std::uint8_t>(std::lround(value));
  };
  return Rgba{mix(0), mix(1), mix(2), 255};
}

std::vector<std::uint8_t> colour_map_texels(int count) {
  std::vector<std::uint8_t> texels;
  texels.reserve(static_cast<std::size_t>(3 * count));
  for (int i = 0; i < count; ++i) {
    const Rgba c = cool_to_warm(count > 1 ? static_cast<double>(i) / (count - 1) : 0.0);
    texels.insert(texels.end(), {c.r, c.g, c.b});
  }
  return texels;
}

}  // namespace incise
