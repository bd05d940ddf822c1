#pragma once
// An MP4 (H.264) from a sequence of pictures, through the `ffmpeg` program (Debian's ffmpeg
// package): frames are piped to it raw, so incise links no codec library.

#include <cstdio>
#include <filesystem>

#include "incise/render/image.hpp"

namespace incise {

/// A video (H.264, in the container the file name says) written by an ffmpeg child process fed
/// raw frames through a pipe.
class VideoWriter {
 public:
  /// Starts ffmpeg writing `path` at `fps` frames/s. Throws Error when ffmpeg is not on PATH.
  VideoWriter(const std::filesystem::path& path, int width, int height, double fps = 30.0);
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  /// Appends a frame; it must have the size given at the start.
  void add(const Image& frame);
  /// Ends the file and waits for ffmpeg; throws Error naming the file if ffmpeg failed.
  void close();

  /// Whether an `ffmpeg` executable is on PATH.
  [[nodiscard]] static bool available();

 private:
  std::filesystem::path path_;
  int width_;
  int height_;
  std::FILE* pipe_ = nullptr;
};

}  // namespace incise
