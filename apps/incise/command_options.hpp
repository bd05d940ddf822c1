#pragma once
// Options shared by the commands that step a scene and draw pictures (run, view).

#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <memory>
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

/// --threads N on `command`, read into `threads` (0: all cores).
inline void add_threads_option(CLI::App& command, int& threads) {
  command
      .add_option("--threads", threads,
                  "Worker threads for element loops and solvers (default: all cores); the "
                  "output is the same for any count")
      ->check(CLI::PositiveNumber);
}

/// Holds TBB to `threads` workers while it lives (nothing for 0).
inline std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads <= 0) {
    return nullptr;
  }
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

}  // namespace incise::app
