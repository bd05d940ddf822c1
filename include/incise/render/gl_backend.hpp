#pragma once
// The OpenGL 3.3 core backend: lit, solid-textured faces (rest-space 3-D textures, one look
// for the exterior and one for cut faces), wireframe, the blade and highlighted lines. It
// draws into whatever framebuffer is bound in the context current on the calling thread:
// an offscreen one (offscreen.hpp) or a window's. Every call, the constructor and destructor
// included, needs that same context current.

#include <array>
#include <cstddef>

#include "incise/render/renderer.hpp"

namespace incise {

/// The OpenGL 3.3 backend of the window and the offscreen pictures. Needs a current context
/// on the calling thread, for its whole life.
class GlBackend final : public RenderBackend {
 public:
  /// Compiles the shaders and makes the textures; throws Error with the driver's log if the
  /// context cannot run them.
  GlBackend();
  ~GlBackend() override;
  void upload_surface(const SurfaceBuffers& buffers) override;
  void upload_positions(std::span<const float> xyz) override;
  void draw(const DrawCall& call) override;

 private:
  unsigned int program_ = 0;
  unsigned int surface_vao_ = 0;
  unsigned int position_buffer_ = 0;
  unsigned int texture_coordinate_buffer_ = 0;
  unsigned int index_buffer_ = 0;
  unsigned int overlay_vao_ = 0;  ///< blade and lines: positions only
  unsigned int overlay_buffer_ = 0;
  std::array<unsigned int, 3> textures_{};  ///< exterior, cut, colour map
  std::size_t exterior_triangles_ = 0;
  std::size_t cut_triangles_ = 0;
  std::size_t position_bytes_ = 0;
};

/// The OpenGL renderer's name and version of the current context ("llvmpipe ... / 4.5 ...").
[[nodiscard]] std::string gl_renderer_name();

}  // namespace incise
