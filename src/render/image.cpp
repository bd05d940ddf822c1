#include "incise/render/image.hpp"

#include <png.h>

#include <algorithm>
#include <string>

#include "incise/core/error.hpp"

namespace incise {

namespace {

constexpr int kMaxSide = 16384;
static_assert(sizeof(Rgba) == 4, "pixels are handed to libpng as packed RGBA bytes");

}  // namespace

Image::Image(int width, int height, Rgba fill) : width_(width), height_(height) {
  if (width <= 0 || height <= 0 || width > kMaxSide || height > kMaxSide) {
    throw InputError("picture size " + std::to_string(width) + "x" + std::to_string(height) +
                     " is not between 1x1 and " + std::to_string(kMaxSide) + " on a side");
  }
  pixels_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), fill);
}

std::size_t Image::index(int x, int y) const {
  INCISE_ASSERT(x >= 0 && y >= 0 && x < width_ && y < height_, "pixel outside the picture");
  return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
         static_cast<std::size_t>(x);
}

void Image::flip_rows() {
  const auto w = static_cast<std::size_t>(width_);
  for (int y = 0; y < height_ / 2; ++y) {
    auto top = pixels_.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(y) * w);
    auto bottom = pixels_.begin() +
                  static_cast<std::ptrdiff_t>(static_cast<std::size_t>(height_ - 1 - y) * w);
    std::swap_ranges(top, top + static_cast<std::ptrdiff_t>(w), bottom);
  }
}

// libpng's simplified API (1.6): no longjmp error handling to carry through C++ frames.
void write_png(const std::filesystem::path& path, const Image& image) {
  INCISE_ASSERT(!image.empty(), "writing an empty picture");
  const std::filesystem::path temporary = path.string() + ".part";
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width());
  png.height = static_cast<png_uint_32>(image.height());
  png.format = PNG_FORMAT_RGBA;
  if (png_image_write_to_file(&png, temporary.c_str(), 0, image.pixels().data(), 0, nullptr) == 0) {
    const std::string message = png.message;
    png_image_free(&png);
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw InputError(path.string(), 0, "cannot write the picture: " + message);
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    throw InputError(path.string(), 0, "cannot write the picture: " + error.message());
  }
}

Image read_png(const std::filesystem::path& path) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&png, path.c_str()) == 0) {
    const std::string message = png.message;
    png_image_free(&png);
    throw InputError(path.string(), 0, "not a readable PNG: " + message);
  }
  png.format = PNG_FORMAT_RGBA;
  if (png.width == 0 || png.height == 0 || png.width > kMaxSide || png.height > kMaxSide) {
    png_image_free(&png);
    throw InputError(path.string(), 0, "the PNG's size is out of range");
  }
  Image image(static_cast<int>(png.width), static_cast<int>(png.height));
  if (png_image_finish_read(&png, nullptr, image.pixels().data(), 0, nullptr) == 0) {
    const std::string message = png.message;
    png_image_free(&png);
    throw InputError(path.string(), 0, "not a readable PNG: " + message);
  }
  return image;
}

}  // namespace incise
