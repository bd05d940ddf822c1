#include "incise/render/solid_texture.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "incise/core/error.hpp"

namespace incise {

namespace {

/// Value noise on a periodic lattice of `cells`^3 random values, smoothly interpolated.
class PeriodicNoise {
 public:
  PeriodicNoise(int cells, std::uint32_t seed) : cells_(cells) {
    std::mt19937 random(seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    values_.resize(static_cast<std::size_t>(cells) * static_cast<std::size_t>(cells) *
                   static_cast<std::size_t>(cells));
    for (double& value : values_) {
      value = uniform(random);
    }
  }
  /// u, v, w in [0, 1): one period of the texture.
  [[nodiscard]] double operator()(double u, double v, double w) const {
    const double x = u * cells_;
    const double y = v * cells_;
    const double z = w * cells_;
    const int i = static_cast<int>(std::floor(x));
    const int j = static_cast<int>(std::floor(y));
    const int k = static_cast<int>(std::floor(z));
    const double fx = smooth(x - i);
    const double fy = smooth(y - j);
    const double fz = smooth(z - k);
    double sum = 0.0;
    for (int c = 0; c < 8; ++c) {
      const int di = c & 1;
      const int dj = (c >> 1) & 1;
      const int dk = (c >> 2) & 1;
      const double weight = (di ? fx : 1.0 - fx) * (dj ? fy : 1.0 - fy) * (dk ? fz : 1.0 - fz);
      sum += weight * value(i + di, j + dj, k + dk);
    }
    return sum;
  }

 private:
  static double smooth(double t) { return t * t * (3.0 - 2.0 * t); }
  [[nodiscard]] double value(int i, int j, int k) const {
    const auto wrap = [&](int a) {
      return static_cast<std::size_t>(((a % cells_) + cells_) % cells_);
    };
    const auto n = static_cast<std::size_t>(cells_);
    return values_[(wrap(k) * n + wrap(j)) * n + wrap(i)];
  }
  int cells_;
  std::vector<double> values_;
};

/// Fractal sum of octaves 4, 8, 16 lattice cells per period, in [0, 1].
double fractal(const std::vector<PeriodicNoise>& octaves, double u, double v, double w) {
  double sum = 0.0;
  double amplitude = 0.5;
  double total = 0.0;
  for (const PeriodicNoise& octave : octaves) {
    sum += amplitude * octave(u, v, w);
    total += amplitude;
    amplitude *= 0.5;
  }
  return sum / total;
}

std::array<double, 3> mix(const std::array<double, 3>& a, const std::array<double, 3>& b,
                          double t) {
  t = std::clamp(t, 0.0, 1.0);
  return {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
}

std::array<double, 3> exterior_colour(const std::vector<PeriodicNoise>& noise, double u, double v,
                                      double w) {
  const double mottle = fractal(noise, u, v, w);
  // Vessels: thin bands where a second noise field crosses its mid value.
  const double field = fractal(noise, w + 0.37, u + 0.11, v + 0.73);
  const double vessel = std::exp(-std::pow((field - 0.5) / 0.018, 2.0));
  const auto base = mix({0.80, 0.55, 0.50}, {0.93, 0.72, 0.66}, 1.6 * (mottle - 0.2));
  return mix(base, {0.62, 0.22, 0.28}, 0.7 * vessel);
}

std::array<double, 3> cut_colour(const std::vector<PeriodicNoise>& noise, double u, double v,
                                 double w) {
  const double mottle = fractal(noise, u, v, w);
  // Fibres along x, bent by the noise.
  const double phase = 2.0 * std::numbers::pi * (4.0 * (v + w) + 1.5 * mottle);
  const double fibre = 0.5 + 0.5 * std::sin(phase);
  const auto base = mix({0.50, 0.09, 0.10}, {0.74, 0.20, 0.18}, 1.5 * (mottle - 0.2));
  return mix(base, {0.38, 0.05, 0.08}, 0.35 * fibre * fibre);
}

}  // namespace

SolidTexture make_tissue_texture(TissueLook look, int size, std::uint32_t seed) {
  INCISE_ASSERT(size >= 4 && size <= 256, "solid texture size out of range");
  std::vector<PeriodicNoise> octaves;
  for (int cells : {4, 8, 16}) {
    octaves.emplace_back(cells, seed * 7919u + static_cast<std::uint32_t>(cells) +
                                    (look == TissueLook::kCut ? 104729u : 0u));
  }
  SolidTexture texture;
  texture.size = size;
  texture.texels.resize(static_cast<std::size_t>(size) * static_cast<std::size_t>(size) *
                        static_cast<std::size_t>(size));
  std::size_t index = 0;
  for (int k = 0; k < size; ++k) {
    for (int j = 0; j < size; ++j) {
      for (int i = 0; i < size; ++i) {
        const double u = static_cast<double>(i) / size;
        const double v = static_cast<double>(j) / size;
        const double w = static_cast<double>(k) / size;
        const auto colour = look == TissueLook::kCut ? cut_colour(octaves, u, v, w)
                                                     : exterior_colour(octaves, u, v, w);
        auto& texel = texture.texels[index++];
        for (int c = 0; c < 3; ++c) {
          texel[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(
              std::lround(255.0 * std::clamp(colour[static_cast<std::size_t>(c)], 0.0, 1.0)));
        }
      }
    }
  }
  return texture;
}

}  // namespace incise
