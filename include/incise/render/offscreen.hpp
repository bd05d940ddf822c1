#pragma once
// Drawing without a display: an OpenGL 3.3 core context from EGL on Mesa's surfaceless
// platform (llvmpipe where there is no GPU), rendering into a multisampled framebuffer and
// read back as an Image. For `incise run --render`, scripted pictures and CI.
//
// Its context is current only while one of its calls runs, so a renderer may be made, used and
// deleted on any thread, one thread at a time (it has no lock of its own).

#include <memory>
#include <string>

#include "incise/render/image.hpp"
#include "incise/render/renderer.hpp"

namespace incise {

/// Pictures without a window: an EGL surfaceless context (Mesa's llvmpipe where there is no
/// GPU), 4x multisampled. One thread uses it.
class OffscreenRenderer final : public ImageRenderer {
 public:
  /// Throws Error saying what is missing when EGL or OpenGL 3.3 cannot be had.
  OffscreenRenderer();
  ~OffscreenRenderer() override;

  /// Draws one frame at options.width x options.height and reads it back.
  [[nodiscard]] Image render(const RenderInput& input, const RenderOptions& options) override;
  /// The OpenGL renderer behind it, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) / 4.5 (Core ...)".
  [[nodiscard]] const std::string& device() const;

 private:
  struct Context;
  std::unique_ptr<Context> context_;
};

}  // namespace incise
