#pragma once
// Pictures of a run: a frame sink that renders every n-th frame (the first and the last
// always) to DIR/frame_NNNNNN.png and, if asked, into an MP4. Its time is the frame's rd.

#include <filesystem>
#include <optional>
#include <vector>

#include "incise/engine/frame_sink.hpp"
#include "incise/render/renderer.hpp"
#include "incise/render/video_writer.hpp"

namespace incise {

/// What `incise run --render` draws and where.
struct PictureOptions {
  std::filesystem::path dir;  ///< pictures go to DIR/frame_NNNNNN.png
  int every = 1;              ///< draw every this many frames
  int last_frame = -1;        ///< drawn even off the `every` grid (-1: unknown; end() draws it)
  /// Size, mode, texture period; the camera is the scene's, else fitted to the body at the
  /// start and kept for the whole run.
  RenderOptions render;
  bool highlight_active = false;               ///< outline the tetrahedra the blade is in
  std::optional<std::filesystem::path> video;  ///< an MP4 of the pictures (needs ffmpeg)
  double video_fps = 30.0;                     ///< the video's frames per second
};

/// A frame sink that draws frames to PNG files (and a video) with an offscreen renderer.
class RenderSink final : public FrameSink {
 public:
  /// Draws with `renderer`, which must outlive the sink.
  RenderSink(ImageRenderer& renderer, PictureOptions options);
  void begin(const Engine& engine) override;
  bool frame(const Engine& engine, const FrameRecord& record) override;
  void end(const Engine& engine) override;
  /// The pictures written so far.
  [[nodiscard]] const std::vector<std::filesystem::path>& pictures() const { return pictures_; }

 private:
  void draw(const Engine& engine);
  ImageRenderer* renderer_;
  PictureOptions options_;
  int drawn_frame_ = -1;
  std::vector<std::filesystem::path> pictures_;
  std::optional<VideoWriter> video_;
};

/// DIR/frame_NNNNNN.png
[[nodiscard]] std::filesystem::path picture_path(const std::filesystem::path& dir, int frame);

}  // namespace incise
