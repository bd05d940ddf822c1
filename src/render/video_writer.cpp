#include "incise/render/video_writer.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <sstream>
#include <string>

#include "incise/core/error.hpp"

namespace incise {

namespace {

/// The argument in single quotes for /bin/sh, quotes inside escaped.
std::string shell_quoted(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) {
    quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  }
  return quoted + "'";
}

}  // namespace

bool VideoWriter::available() {
  const char* path = std::getenv("PATH");
  if (path == nullptr) {
    return false;
  }
  std::stringstream folders(path);
  std::string folder;
  while (std::getline(folders, folder, ':')) {
    const std::string candidate = (folder.empty() ? std::string(".") : folder) + "/ffmpeg";
    if (::access(candidate.c_str(), X_OK) == 0) {
      return true;
    }
  }
  return false;
}

VideoWriter::VideoWriter(const std::filesystem::path& path, int width, int height, double fps)
    : path_(path), width_(width), height_(height) {
  if (!available()) {
    throw Error("writing " + path.string() +
                " needs the ffmpeg program on PATH (Debian: apt-get install ffmpeg)");
  }
  if (!(fps > 0.0)) {
    throw InputError("video frame rate must be positive");
  }
  // H.264 in yuv420p wants even sides: pad by a pixel where needed.
  const std::string command =
      "ffmpeg -loglevel error -y -f rawvideo -pix_fmt rgba -s " + std::to_string(width) + "x" +
      std::to_string(height) + " -r " + std::to_string(fps) +
      " -i - -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -c:v libx264 -pix_fmt yuv420p -crf 20 " +
      "-movflags +faststart " + shell_quoted(path.string());
  pipe_ = ::popen(command.c_str(), "w");
  if (pipe_ == nullptr) {
    throw Error("cannot start ffmpeg to write " + path.string());
  }
}

VideoWriter::~VideoWriter() {
  if (pipe_ != nullptr) {
    ::pclose(pipe_);
  }
}

void VideoWriter::add(const Image& frame) {
  INCISE_ASSERT(pipe_ != nullptr, "adding a frame to a closed video");
  if (frame.width() != width_ || frame.height() != height_) {
    throw InputError("a " + std::to_string(frame.width()) + "x" + std::to_string(frame.height()) +
                     " frame for a " + std::to_string(width_) + "x" + std::to_string(height_) +
                     " video");
  }
  const std::size_t bytes = frame.pixels().size() * sizeof(Rgba);
  if (std::fwrite(frame.pixels().data(), 1, bytes, pipe_) != bytes) {
    throw Error("ffmpeg stopped taking frames for " + path_.string());
  }
}

void VideoWriter::close() {
  if (pipe_ == nullptr) {
    return;
  }
  const int status = ::pclose(pipe_);
  pipe_ = nullptr;
  if (status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw Error("ffmpeg failed to write " + path_.string());
  }
}

}  // namespace incise
