#pragma once
// An RGBA picture in memory, rows from the top, and PNG files (libpng) for it.

#include <cstdint>
#include <filesystem>
#include <vector>

namespace incise {

/// A pixel, 8 bits per channel.
struct Rgba {
  std::uint8_t r = 0;    ///< red
  std::uint8_t g = 0;    ///< green
  std::uint8_t b = 0;    ///< blue
  std::uint8_t a = 255;  ///< opacity
  /// The same four channels.
  friend bool operator==(const Rgba&, const Rgba&) = default;
};

/// A picture in memory, top row first.
class Image {
 public:
  Image() = default;
  /// A width x height picture filled with `fill`; throws InputError for a size that is not
  /// positive or above 16384 on a side.
  Image(int width, int height, Rgba fill = {});

  /// Pixels per row.
  [[nodiscard]] int width() const { return width_; }
  /// Rows.
  [[nodiscard]] int height() const { return height_; }
  /// Whether it has no pixel.
  [[nodiscard]] bool empty() const { return pixels_.empty(); }
  /// The pixel in column x of row y (0: top).
  [[nodiscard]] Rgba& at(int x, int y) { return pixels_[index(x, y)]; }
  /// The same, read only.
  [[nodiscard]] const Rgba& at(int x, int y) const { return pixels_[index(x, y)]; }
  /// Every pixel, row after row.
  [[nodiscard]] std::vector<Rgba>& pixels() { return pixels_; }
  /// The same, read only.
  [[nodiscard]] const std::vector<Rgba>& pixels() const { return pixels_; }
  /// Mirrors the rows (OpenGL reads pictures bottom row first).
  void flip_rows();

 private:
  [[nodiscard]] std::size_t index(int x, int y) const;
  int width_ = 0;
  int height_ = 0;
  std::vector<Rgba> pixels_;
};

/// Writes an 8-bit RGBA PNG, atomically (a temporary renamed over the file); errors name it.
void write_png(const std::filesystem::path& path, const Image& image);
/// Reads a PNG of any colour type as 8-bit RGBA; an unreadable file is an InputError naming it.
[[nodiscard]] Image read_png(const std::filesystem::path& path);

}  // namespace incise
