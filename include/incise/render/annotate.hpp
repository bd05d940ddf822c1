#pragma once
// What a picture needs to say what it shows: text (a title, the view's name), a colour bar
// with its unit and ticks, and two pictures side by side. Text is drawn in stb_easy_font's
// built-in font (Debian's libstb-dev): no font file to find at run time, the same pixels on
// every machine. Pure functions of the pictures they are given.

#include <string>
#include <string_view>

#include "incise/render/image.hpp"

namespace incise {

/// stb_easy_font's glyphs are 7 units tall (capitals) on a 12-unit line.
inline constexpr int kTextLineUnits = 12;

/// Draws `text` (printable ASCII; others show as nothing) with its top left at (x, y),
/// `scale` pixels per font unit; pixels outside the picture are skipped.
void draw_text(Image& image, int x, int y, std::string_view text, int scale, Rgba colour);

/// The width in pixels of `text` drawn at `scale`.
[[nodiscard]] int text_width(std::string_view text, int scale);

/// A vertical colour bar of ParaView's Cool to Warm map (cool_to_warm) along the picture's
/// right edge, `low` at the bottom and `high` at the top, with five ticks labelled in the
/// value's units and `label` (say "displacement (mm)") under it, drawn in `ink`; it starts
/// below two lines of title.
void draw_colour_bar(Image& image, double low, double high, std::string_view label, Rgba ink);

/// The two pictures side by side (heights may differ: the shorter is padded with `fill`).
[[nodiscard]] Image side_by_side(const Image& left, const Image& right, Rgba fill);

}  // namespace incise
