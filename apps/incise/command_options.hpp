#pragma once
// Option values shared by the commands that draw pictures (run --render, view).

#include <sstream>
#include <string>
#include <utility>

#include "incise/core/error.hpp"
#include "incise/render/renderer.hpp"

namespace incise::app {

/// "WxH" (pixels) -> (W, H); an InputError naming --size otherwise.
inline std::pair<int, int> parse_size(const std::string& text) {
  int width = 0;
  int height = 0;
  char separator = 0;
  std::istringstream stream(text);
  if (!(stream >> width >> separator >> height) || (separator != 'x' && separator != 'X') ||
      !stream.eof() || width < 16 || height < 16 || width > 8192 || height > 8192) {
    throw InputError("--size " + text + ": expected WxH, e.g. 800x600, each side 16 to 8192");
  }
  return {width, height};
}

/// faces, wire or cut; an InputError naming --mode otherwise.
inline RenderMode parse_mode(const std::string& text) {
  const auto mode = parse_render_mode(text);
  if (!mode) {
    throw InputError("--mode " + text + ": expected faces, wire or cut");
  }
  return *mode;
}

}  // namespace incise::app
