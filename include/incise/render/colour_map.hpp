#pragma once
// Colour maps for a scalar on a surface (a predicted displacement, say): ParaView's default,
// "Cool to Warm" (Moreland 2009), so a picture reads as the same data does in ParaView and
// 3D Slicer. Pure functions.

#include <cstdint>
#include <vector>

#include "incise/render/image.hpp"

namespace incise {

/// The colour of t in [0, 1] (clamped; NaN is the low end): blue (59, 76, 192) through grey
/// (221, 221, 221) to red (180, 4, 38), linear in RGB between Moreland's samples at eighths.
[[nodiscard]] Rgba cool_to_warm(double t);

/// `count` colours from t = 0 to 1, three bytes (RGB) each: a 1-D texture of the map.
[[nodiscard]] std::vector<std::uint8_t> colour_map_texels(int count);

}  // namespace incise
