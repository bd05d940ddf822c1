#include "incise/render/offscreen.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <array>
#include <charconv>
#include <optional>
#include <string>

#include "incise/core/error.hpp"
#include "incise/render/gl_backend.hpp"

namespace incise {

namespace {

constexpr int kSamples = 4;  ///< multisampling: smooth edges in pictures and video

[[noreturn]] void fail(const char* what) {
  std::array<char, 16> hex{};
  const auto code = static_cast<unsigned>(eglGetError());
  const auto end = std::to_chars(hex.data(), hex.data() + hex.size(), code, 16).ptr;
  throw Error(std::string("offscreen rendering: ") + what + " (EGL error 0x" +
              std::string(hex.data(), end) +
              "); it needs Mesa's EGL and OpenGL 3.3: apt-get install libegl1 libegl-mesa0 "
              "libgl1-mesa-dri");
}

/// Mesa's surfaceless platform needs no display server; any other EGL display will do too.
EGLDisplay open_display() {
  const auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  EGLDisplay display = EGL_NO_DISPLAY;
  if (get_platform_display != nullptr) {
    display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  }
  EGLint major = 0;
  EGLint minor = 0;
  if (display != EGL_NO_DISPLAY && eglInitialize(display, &major, &minor) == EGL_TRUE) {
    return display;
  }
  display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
  if (display == EGL_NO_DISPLAY || eglInitialize(display, &major, &minor) != EGL_TRUE) {
    fail("no EGL display");
  }
  return display;
}

}  // namespace

struct OffscreenRenderer::Context {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  std::string device;
  std::optional<GlBackend> backend;
  std::optional<Renderer> renderer;
  // Multisampled framebuffer drawn into, and a plain one it resolves to for reading.
  GLuint framebuffer = 0;
  GLuint colour = 0;
  GLuint depth = 0;
  GLuint resolved_framebuffer = 0;
  GLuint resolved_colour = 0;
  int width = 0;
  int height = 0;

  void make_current() const {
    if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
      fail("cannot make the OpenGL context current");
    }
  }

  /// Lets go of the context on this thread. EGL lets a context be current on one thread only:
  /// held between calls, a renderer could not be used (nor deleted) from another thread.
  void release() const { eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT); }

  /// The context current on this thread for one call, released when it returns or throws.
  class CurrentFor {
   public:
    explicit CurrentFor(const Context& context) : context_(context) { context_.make_current(); }
    ~CurrentFor() { context_.release(); }
    CurrentFor(const CurrentFor&) = delete;
    CurrentFor& operator=(const CurrentFor&) = delete;

   private:
    const Context& context_;
  };

  void resize(int new_width, int new_height) {
    if (new_width == width && new_height == height) {
      return;
    }
    release_framebuffers();
    glGenFramebuffers(1, &framebuffer);
    glGenRenderbuffers(1, &colour);
    glGenRenderbuffers(1, &depth);
    glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
    glBindRenderbuffer(GL_RENDERBUFFER, colour);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, kSamples, GL_RGBA8, new_width, new_height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, kSamples, GL_DEPTH_COMPONENT24, new_width,
                                     new_height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    const bool drawable = glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
    glGenFramebuffers(1, &resolved_framebuffer);
    glGenRenderbuffers(1, &resolved_colour);
    glBindFramebuffer(GL_FRAMEBUFFER, resolved_framebuffer);
    glBindRenderbuffer(GL_RENDERBUFFER, resolved_colour);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, new_width, new_height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                              resolved_colour);
    if (!drawable || glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      throw Error("offscreen rendering: OpenGL cannot make a " + std::to_string(new_width) + "x" +
                  std::to_string(new_height) + " framebuffer");
    }
    width = new_width;
    height = new_height;
  }

  void release_framebuffers() {
    if (framebuffer != 0) {
      glDeleteFramebuffers(1, &framebuffer);
      glDeleteFramebuffers(1, &resolved_framebuffer);
      const std::array<GLuint, 3> buffers{colour, depth, resolved_colour};
      glDeleteRenderbuffers(static_cast<GLsizei>(buffers.size()), buffers.data());
      framebuffer = 0;
    }
    width = height = 0;
  }

  Image read() const {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, resolved_framebuffer);
    glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, resolved_framebuffer);
    Image image(width, height);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, image.pixels().data());
    image.flip_rows();
    return image;
  }
};

OffscreenRenderer::OffscreenRenderer() : context_(std::make_unique<Context>()) {
  Context& c = *context_;
  c.display = open_display();
  if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE) {
    fail("EGL has no desktop OpenGL");
  }
  const std::array<EGLint, 5> config_attributes{EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                                EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (eglChooseConfig(c.display, config_attributes.data(), &config, 1, &configs) != EGL_TRUE ||
      configs == 0) {
    fail("no EGL configuration for OpenGL");
  }
  const std::array<EGLint, 7> context_attributes{EGL_CONTEXT_MAJOR_VERSION,
                                                 3,
                                                 EGL_CONTEXT_MINOR_VERSION,
                                                 3,
                                                 EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                                 EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                                 EGL_NONE};
  c.context = eglCreateContext(c.display, config, EGL_NO_CONTEXT, context_attributes.data());
  if (c.context == EGL_NO_CONTEXT) {
    fail("no OpenGL 3.3 core context");
  }
  const Context::CurrentFor current(c);
  c.device = gl_renderer_name();
  c.backend.emplace();
  c.renderer.emplace(*c.backend);
}

OffscreenRenderer::~OffscreenRenderer() {
  Context& c = *context_;
  if (c.context != EGL_NO_CONTEXT) {
    // GL objects go while their context is current (released after every call, so it can be
    // made current here, whichever thread this is); the display stays initialised, as other
    // renderers in the process may share it.
    eglMakeCurrent(c.display, EGL_NO_SURFACE, EGL_NO_SURFACE, c.context);
    c.renderer.reset();
    c.backend.reset();
    c.release_framebuffers();
    c.release();
    eglDestroyContext(c.display, c.context);
  }
}

Image OffscreenRenderer::render(const RenderInput& input, const RenderOptions& options) {
  Context& c = *context_;
  const Context::CurrentFor current(c);
  c.resize(options.width, options.height);
  glBindFramebuffer(GL_FRAMEBUFFER, c.framebuffer);
  c.renderer->render(input, options);
  return c.read();
}

const std::string& OffscreenRenderer::device() const {
  return context_->device;
}

}  // namespace incise
