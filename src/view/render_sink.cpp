#include "incise/view/render_sink.hpp"

#include <fmt/format.h>

#include "incise/core/error.hpp"
#include "incise/view/frame_scene.hpp"

namespace incise {

std::filesystem::path picture_path(const std::filesystem::path& dir, int frame) {
  return dir / fmt::format("frame_{:06d}.png", frame);
}

RenderSink::RenderSink(ImageRenderer& renderer, PictureOptions options)
    : renderer_(&renderer), options_(std::move(options)) {
  if (options_.every < 1) {
    throw InputError("pictures: --render-every must be at least 1");
  }
  std::error_code error;
  std::filesystem::create_directories(options_.dir, error);
  if (error) {
    throw InputError(options_.dir.string(), 0,
                     "cannot make the picture folder: " + error.message());
  }
  if (options_.video) {
    video_.emplace(*options_.video, options_.render.width, options_.render.height,
                   options_.video_fps);
  }
}

void RenderSink::begin(const Engine& engine) {
  const double aspect = static_cast<double>(options_.render.width) / options_.render.height;
  options_.render.camera = scene_camera(engine.scene(), frame_scene(engine).bounds(), aspect);
  draw(engine);
}

bool RenderSink::frame(const Engine& engine, const FrameRecord& record) {
  if (record.frame % options_.every != 0 && record.frame != options_.last_frame) {
    return false;
  }
  draw(engine);
  return true;
}

void RenderSink::end(const Engine& engine) {
  if (drawn_frame_ != engine.frame()) {
    draw(engine);
  }
  if (video_) {
    video_->close();
  }
}

void RenderSink::draw(const Engine& engine) {
  const FrameScene scene = frame_scene(engine, options_.highlight_active);
  const Image image = renderer_->render(scene.input(), options_.render);
  const std::filesystem::path path = picture_path(options_.dir, engine.frame());
  write_png(path, image);
  pictures_.push_back(path);
  if (video_) {
    video_->add(image);
  }
  drawn_frame_ = engine.frame();
}

}  // namespace incise
