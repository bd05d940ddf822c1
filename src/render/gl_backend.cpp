#include "incise/render/gl_backend.hpp"

// Core-profile entry points come straight from glvnd's libOpenGL (it dispatches to whichever
// context is current, EGL or GLX), so no loader library is needed.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/render/colour_map.hpp"
#include "incise/render/solid_texture.hpp"

namespace incise {

namespace {

constexpr const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_texture_coordinate;
uniform mat4 u_view_projection;
out vec3 v_world;
out vec3 v_texture_coordinate;
void main() {
  v_world = a_position;
  v_texture_coordinate = a_texture_coordinate;
  gl_Position = u_view_projection * vec4(a_position, 1.0);
}
)";

// Flat shading from screen-space derivatives: every face, new ones included, gets its own
// normal without a normal buffer. Two-sided: a face seen from behind is lit as its front.
constexpr const char* kFragmentShader = R"(#version 330 core
in vec3 v_world;
in vec3 v_texture_coordinate;
uniform sampler3D u_texture;
uniform int u_shading;  // 0: textured and lit, 1: flat colour lit, 2: flat colour unlit
uniform vec3 u_colour;
uniform vec3 u_eye;
out vec4 o_colour;
void main() {
  vec3 base = u_shading == 0 ? texture(u_texture, v_texture_coordinate).rgb : u_colour;
  if (u_shading == 2) {
    o_colour = vec4(base, 1.0);
    return;
  }
  vec3 n = normalize(cross(dFdx(v_world), dFdy(v_world)));
  vec3 v = normalize(u_eye - v_world);
  if (dot(n, v) < 0.0) n = -n;
  vec3 key = normalize(v + vec3(0.0, 0.0, 0.8));
  float diffuse = 0.55 * max(dot(n, v), 0.0) + 0.35 * max(dot(n, key), 0.0);
  float specular = 0.18 * pow(max(dot(reflect(-key, n), v), 0.0), 32.0);
  o_colour = vec4(base * (0.18 + diffuse) + vec3(specular), 1.0);
}
)";

/// The driver's log of a shader or program (glGetShaderInfoLog / glGetProgramInfoLog).
std::string info_log(GLuint object, void (*get_log)(GLuint, GLsizei, GLsizei*, GLchar*)) {
  std::string log(4096, '\0');
  GLsizei length = 0;
  get_log(object, static_cast<GLsizei>(log.size()), &length, log.data());
  log.resize(static_cast<std::size_t>(length));
  return log;
}

GLuint compile(GLenum kind, const char* source) {
  const GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    const std::string log = info_log(shader, glGetShaderInfoLog);
    glDeleteShader(shader);
    throw Error("OpenGL could not compile incise's shader: " + log);
  }
  return shader;
}

GLuint link_program() {
  const GLuint vertex = compile(GL_VERTEX_SHADER, kVertexShader);
  const GLuint fragment = compile(GL_FRAGMENT_SHADER, kFragmentShader);
  const GLuint program = glCreateProgram();
  glAttachShader(program, vertex);
  glAttachShader(program, fragment);
  glLinkProgram(program);
  glDeleteShader(vertex);
  glDeleteShader(fragment);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    const std::string log = info_log(program, glGetProgramInfoLog);
    glDeleteProgram(program);
    throw Error("OpenGL could not link incise's shaders: " + log);
  }
  return program;
}

GLuint make_texture(const SolidTexture& texture) {
  GLuint id = 0;
  glGenTextures(1, &id);
  glBindTexture(GL_TEXTURE_3D, id);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage3D(GL_TEXTURE_3D, 0, GL_RGB8, texture.size, texture.size, texture.size, 0, GL_RGB,
               GL_UNSIGNED_BYTE, texture.texels.data());
  glGenerateMipmap(GL_TEXTURE_3D);
  for (GLenum axis : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R}) {
    glTexParameteri(GL_TEXTURE_3D, axis, GL_REPEAT);
  }
  glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  return id;
}

/// The colour map as a 3-D texture one texel high and deep, clamped at its ends.
GLuint make_colour_map_texture() {
  constexpr int kTexels = 256;
  const std::vector<std::uint8_t> texels = colour_map_texels(kTexels);
  GLuint id = 0;
  glGenTextures(1, &id);
  glBindTexture(GL_TEXTURE_3D, id);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage3D(GL_TEXTURE_3D, 0, GL_RGB8, kTexels, 1, 1, 0, GL_RGB, GL_UNSIGNED_BYTE,
               texels.data());
  for (GLenum axis : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R}) {
    glTexParameteri(GL_TEXTURE_3D, axis, GL_CLAMP_TO_EDGE);
  }
  glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  return id;
}

void* byte_offset(std::size_t bytes) {
  return reinterpret_cast<void*>(bytes);  // NOLINT: OpenGL's buffer offsets are pointers
}

}  // namespace

std::string gl_renderer_name() {
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  return std::string(renderer != nullptr ? renderer : "?") + " / " +
         (version != nullptr ? version : "?");
}

GlBackend::GlBackend() {
  program_ = link_program();
  glGenVertexArrays(1, &surface_vao_);
  glGenBuffers(1, &position_buffer_);
  glGenBuffers(1, &texture_coordinate_buffer_);
  glGenBuffers(1, &index_buffer_);
  glBindVertexArray(surface_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, position_buffer_);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  glEnableVertexAttribArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, texture_coordinate_buffer_);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  glEnableVertexAttribArray(1);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer_);
  glGenVertexArrays(1, &overlay_vao_);
  glGenBuffers(1, &overlay_buffer_);
  glBindVertexArray(overlay_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, overlay_buffer_);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  glEnableVertexAttribArray(0);
  glBindVertexArray(0);
  textures_[0] = make_texture(make_tissue_texture(TissueLook::kExterior));
  textures_[1] = make_texture(make_tissue_texture(TissueLook::kCut));
  textures_[2] = make_colour_map_texture();
  if (glGetError() != GL_NO_ERROR) {
    throw Error("OpenGL refused to set up incise's buffers and textures");
  }
}

GlBackend::~GlBackend() {
  glDeleteTextures(static_cast<GLsizei>(textures_.size()), textures_.data());
  const std::array<GLuint, 4> buffers{position_buffer_, texture_coordinate_buffer_, index_buffer_,
                                      overlay_buffer_};
  glDeleteBuffers(static_cast<GLsizei>(buffers.size()), buffers.data());
  const std::array<GLuint, 2> arrays{surface_vao_, overlay_vao_};
  glDeleteVertexArrays(static_cast<GLsizei>(arrays.size()), arrays.data());
  glDeleteProgram(program_);
}

void GlBackend::upload_surface(const SurfaceBuffers& buffers) {
  glBindVertexArray(surface_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, texture_coordinate_buffer_);
  glBufferData(GL_ARRAY_BUFFER,
               static_cast<GLsizeiptr>(buffers.texture_coordinates.size() * sizeof(float)),
               buffers.texture_coordinates.data(), GL_STATIC_DRAW);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer_);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER,
               static_cast<GLsizeiptr>(buffers.indices.size() * sizeof(std::uint32_t)),
               buffers.indices.data(), GL_STATIC_DRAW);
  glBindVertexArray(0);
  exterior_triangles_ = buffers.exterior_triangles;
  cut_triangles_ = buffers.cut_triangles;
  position_bytes_ = 0;  // the next positions need a buffer of the new size
}

void GlBackend::upload_positions(std::span<const float> xyz) {
  glBindBuffer(GL_ARRAY_BUFFER, position_buffer_);
  const std::size_t bytes = xyz.size() * sizeof(float);
  if (bytes != position_bytes_) {
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(bytes), xyz.data(), GL_STREAM_DRAW);
    position_bytes_ = bytes;
  } else {
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(bytes), xyz.data());
  }
}

void GlBackend::draw(const DrawCall& call) {
  glViewport(0, 0, call.width, call.height);
  glClearColor(call.background.r / 255.0F, call.background.g / 255.0F, call.background.b / 255.0F,
               1.0F);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  if (call.cull_back_faces) {
    glCullFace(GL_BACK);  // counter-clockwise faces are front faces (OpenGL's default)
    glEnable(GL_CULL_FACE);
  } else {
    glDisable(GL_CULL_FACE);
  }
  glUseProgram(program_);
  glUniformMatrix4fv(glGetUniformLocation(program_, "u_view_projection"), 1, GL_FALSE,
                     call.view_projection.data());
  glUniform3fv(glGetUniformLocation(program_, "u_eye"), 1, call.eye.data());
  glUniform1i(glGetUniformLocation(program_, "u_texture"), 0);
  const GLint shading = glGetUniformLocation(program_, "u_shading");
  const GLint colour = glGetUniformLocation(program_, "u_colour");
  glActiveTexture(GL_TEXTURE0);

  glBindVertexArray(surface_vao_);
  const auto draw_triangles = [](std::size_t first, std::size_t count) {
    if (count > 0) {
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(3 * count), GL_UNSIGNED_INT,
                     byte_offset(3 * first * sizeof(std::uint32_t)));
    }
  };
  glUniform1i(shading, 0);
  if (call.mode == RenderMode::kWire) {
    glEnable(GL_POLYGON_OFFSET_FILL);  // faces behind their own edges
    glPolygonOffset(1.0F, 1.0F);
  }
  if (call.mode != RenderMode::kCut) {
    glBindTexture(GL_TEXTURE_3D, textures_[call.colour_mapped ? 2 : 0]);
    draw_triangles(0, exterior_triangles_);
  }
  glBindTexture(GL_TEXTURE_3D, textures_[call.colour_mapped ? 2 : 1]);
  draw_triangles(exterior_triangles_, cut_triangles_);
  glDisable(GL_POLYGON_OFFSET_FILL);
  if (call.mode == RenderMode::kWire) {
    glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    glUniform1i(shading, 2);
    glUniform3f(colour, 0.12F, 0.10F, 0.10F);
    draw_triangles(0, exterior_triangles_ + cut_triangles_);
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
  }
  glDisable(GL_CULL_FACE);  // the blade is seen from both sides

  glBindVertexArray(overlay_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, overlay_buffer_);
  if (!call.blade_quad.empty()) {
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(call.blade_quad.size() * sizeof(float)),
                 call.blade_quad.data(), GL_STREAM_DRAW);
    glUniform1i(shading, 1);
    glUniform3f(colour, 0.78F, 0.80F, 0.84F);
    glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(call.blade_quad.size() / 3));
  }
  glDisable(GL_DEPTH_TEST);  // highlights show through the body
  glUniform1i(shading, 2);
  for (const auto& [lines, rgb] : {std::pair{&call.lines, std::array{1.0F, 0.85F, 0.1F}},
                                   std::pair{&call.cut_lines, std::array{0.1F, 0.9F, 1.0F}}}) {
    if (lines->empty()) {
      continue;
    }
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(lines->size() * sizeof(float)),
                 lines->data(), GL_STREAM_DRAW);
    glUniform3f(colour, rgb[0], rgb[1], rgb[2]);
    glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(lines->size() / 3));
  }
  glEnable(GL_DEPTH_TEST);
  glBindVertexArray(0);
  if (const GLenum error = glGetError(); error != GL_NO_ERROR) {
    throw Error("OpenGL error " + std::to_string(error) + " while drawing a frame");
  }
}

}  // namespace incise
