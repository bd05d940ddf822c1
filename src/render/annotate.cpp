#include "incise/render/annotate.hpp"

#include <fmt/format.h>
#include <stb/stb_easy_font.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <vector>

#include "incise/render/colour_map.hpp"

namespace incise {

namespace {

/// stb_easy_font's vertex: x, y, z and a colour, four per quad.
struct FontVertex {
  float x, y, z;
  std::array<unsigned char, 4> colour;
};

void fill_rectangle(Image& image, int x0, int y0, int x1, int y1, Rgba colour) {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, image.width());
  y1 = std::min(y1, image.height());
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      image.at(x, y) = colour;
    }
  }
}

std::string printable(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (c < 32 || c > 126) {
      c = ' ';
    }
  }
  return out;
}

}  // namespace

void draw_text(Image& image, int x, int y, std::string_view text, int scale, Rgba colour) {
  std::string line = printable(text);
  // About 270 quads of 64 bytes per 1,000 characters (stb_easy_font's estimate).
  std::vector<FontVertex> vertices(4 * (line.size() * 30 + 4));
  const int quads = stb_easy_font_print(0.0F, 0.0F, line.data(), nullptr, vertices.data(),
                                        static_cast<int>(vertices.size() * sizeof(FontVertex)));
  for (int q = 0; q < quads; ++q) {
    const FontVertex* corner = &vertices[static_cast<std::size_t>(4 * q)];
    float low_x = corner[0].x;
    float low_y = corner[0].y;
    float high_x = corner[0].x;
    float high_y = corner[0].y;
    for (int c = 1; c < 4; ++c) {
      low_x = std::min(low_x, corner[c].x);
      low_y = std::min(low_y, corner[c].y);
      high_x = std::max(high_x, corner[c].x);
      high_y = std::max(high_y, corner[c].y);
    }
    fill_rectangle(image, x + static_cast<int>(std::lround(low_x * static_cast<float>(scale))),
                   y + static_cast<int>(std::lround(low_y * static_cast<float>(scale))),
                   x + static_cast<int>(std::lround(high_x * static_cast<float>(scale))),
                   y + static_cast<int>(std::lround(high_y * static_cast<float>(scale))), colour);
  }
}

int text_width(std::string_view text, int scale) {
  std::string line = printable(text);
  return stb_easy_font_width(line.data()) * scale;
}

void draw_colour_bar(Image& image, double low, double high, std::string_view label, Rgba ink) {
  const int scale = std::max(1, image.height() / 300);
  const int line = kTextLineUnits * scale;
  const int bar_width = std::max(8, image.width() / 40);
  const int top = 5 * line / 2;                  // below a title's two lines
  const int bottom = image.height() - 2 * line;  // the label under it
  if (bottom - top < 2 * line) {
    return;  // no room
  }
  // Tick labels to the left of the bar: room for the widest one.
  std::array<std::string, 5> ticks;
  int widest = 0;
  const double span = high - low;
  const int decimals =
      span > 0.0 ? std::clamp(2 - static_cast<int>(std::floor(std::log10(span))), 0, 4) : 1;
  for (std::size_t t = 0; t < ticks.size(); ++t) {
    ticks[t] = fmt::format("{:.{}f}", low + span * static_cast<double>(t) / 4.0, decimals);
    widest = std::max(widest, text_width(ticks[t], scale));
  }
  const int right = image.width() - line;
  const int left = right - bar_width;
  for (int y = top; y < bottom; ++y) {
    const double t = static_cast<double>(bottom - 1 - y) / static_cast<double>(bottom - 1 - top);
    fill_rectangle(image, left, y, right, y + 1, cool_to_warm(t));
  }
  // A frame, and the ticks.
  fill_rectangle(image, left - 1, top - 1, right + 1, top, ink);
  fill_rectangle(image, left - 1, bottom, right + 1, bottom + 1, ink);
  fill_rectangle(image, left - 1, top, left, bottom, ink);
  fill_rectangle(image, right, top, right + 1, bottom, ink);
  for (std::size_t t = 0; t < ticks.size(); ++t) {
    const int y = bottom - static_cast<int>(std::lround(static_cast<double>(bottom - top) *
                                                        static_cast<double>(t) / 4.0));
    fill_rectangle(image, left - scale * 3, y, left, y + std::max(1, scale / 2), ink);
    draw_text(image, left - scale * 4 - text_width(ticks[t], scale), y - 4 * scale, ticks[t], scale,
              ink);
  }
  draw_text(image, std::max(0, right - text_width(label, scale)), bottom + line / 2, label, scale,
            ink);
  (void)widest;
}

Image side_by_side(const Image& left, const Image& right, Rgba fill) {
  Image joined(left.width() + right.width(), std::max(left.height(), right.height()), fill);
  for (int y = 0; y < left.height(); ++y) {
    for (int x = 0; x < left.width(); ++x) {
      joined.at(x, y) = left.at(x, y);
    }
  }
  for (int y = 0; y < right.height(); ++y) {
    for (int x = 0; x < right.width(); ++x) {
      joined.at(left.width() + x, y) = right.at(x, y);
    }
  }
  return joined;
}

}  // namespace incise
