#pragma once
// What the renderer draws and how, independent of the graphics API: a body's boundary
// surface (exterior and cut faces, each with its own solid texture looked up at rest-space
// coordinates), the blade, and highlighted segments. A RenderBackend puts it on screen:
// OpenGL (gl_backend.hpp) or the null backend of the tests. The render module depends on
// the mesh's types only, not on physics or the engine.
//
// Buffers follow the surface: its topology and texture coordinates are uploaded again only
// when its revision changes; positions are streamed every frame.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/render/camera.hpp"
#include "incise/render/image.hpp"

namespace incise {

/// The seed's demo keys: F (faces), G (wireframe over faces), C (cut faces only).
enum class RenderMode : std::uint8_t { kFaces, kWire, kCut };
[[nodiscard]] std::string_view name_of(RenderMode mode);
/// "faces", "wire" or "cut"; nullopt otherwise.
[[nodiscard]] std::optional<RenderMode> parse_render_mode(std::string_view name);

/// One frame's scene. Spans must stay valid during render().
struct RenderInput {
  /// Changes whenever triangles, cut marks or rest positions change (a mesh revision).
  std::uint64_t surface_revision = 0;
  std::span<const Triangle> triangles;   ///< outward, ids into positions
  std::span<const std::uint8_t> on_cut;  ///< per triangle: 1 on a cut, 0 exterior
  std::span<const Vec3> rest_positions;  ///< per vertex (m): where the texture is looked up
  std::span<const Vec3> positions;       ///< per vertex, current (m)
  /// The blade as a segment, tip then base (m), if the tool is on.
  std::optional<std::array<Vec3, 2>> blade;
  /// Lines drawn on top: the active tetrahedra's edges (yellow) and the edges on the cut
  /// among them (cyan), m.
  std::span<const std::array<Vec3, 2>> highlights;
  std::span<const std::array<Vec3, 2>> cut_edges;  ///< the cut's edges among the highlights
  /// Per vertex: when given, the surface is coloured by this scalar (cool_to_warm over
  /// RenderOptions::scalar_range) instead of textured. Part of the surface: a change needs a
  /// new surface_revision.
  std::span<const double> scalars;
};

/// How a frame is drawn.
struct RenderOptions {
  int width = 800;                       ///< pixels
  int height = 600;                      ///< pixels
  RenderMode mode = RenderMode::kFaces;  ///< faces, wire or cut faces alone
  Camera camera;                         ///< where it is seen from
  /// Rest-space length of one tile of the solid textures (m).
  double texture_period = 0.02;
  Rgba background{38, 42, 52, 255};  ///< the clear colour
  bool draw_blade = true;            ///< draw the blade when the input has one
  /// The scalars' values at the blue and the red end of the colour map.
  std::array<double, 2> scalar_range{0.0, 1.0};
  /// Draw back faces even where the surface is closed (they are hidden then: for tests).
  bool two_sided = false;
};

/// The CPU side of the surface's buffers: built once per surface revision.
struct SurfaceBuffers {
  std::uint64_t revision = 0;      ///< the input's surface_revision they were built for
  std::vector<VertexId> vertices;  ///< the surface's mesh vertices, in buffer order
  /// One past the largest of `vertices`: the positions a frame must give to be drawn with them.
  std::size_t positions_needed = 0;
  std::vector<std::uint32_t> indices;      ///< into `vertices`: exterior triangles, then cut ones
  std::size_t exterior_triangles = 0;      ///< triangles of the body's outside, first in indices
  std::size_t cut_triangles = 0;           ///< triangles on the cut, after them
  std::vector<float> texture_coordinates;  ///< 3 per buffer vertex: rest position / period
  /// Coloured by scalars: each texture coordinate is (t, 0.5, 0.5), t the scalar's place in
  /// the range, into the colour map.
  bool colour_mapped = false;
  /// Every edge is used as often in one direction as in the other, and the rest volume it
  /// encloses is positive: the surface bounds solids and faces out, so from outside its back
  /// faces are always behind front faces and need not be drawn.
  bool closed_outward = false;
};

/// Whether `triangles` bound solids and face out (SurfaceBuffers::closed_outward), at
/// `positions`.
[[nodiscard]] bool closed_and_facing_out(std::span<const Triangle> triangles,
                                         std::span<const Vec3> positions);

/// Builds the buffers of `input`'s surface. Throws InputError naming the triangle if it
/// refers to a vertex that has no position (or scalar), or a rest position is not finite.
[[nodiscard]] SurfaceBuffers build_surface_buffers(const RenderInput& input, double texture_period,
                                                   std::array<double, 2> scalar_range = {0.0, 1.0});
/// Current positions of the buffer's vertices, 3 floats each.
void gather_positions(const SurfaceBuffers& buffers, std::span<const Vec3> positions,
                      std::vector<float>& out);

/// Everything but the surface a backend needs to draw one frame.
struct DrawCall {
  int width = 0;                         ///< pixels
  int height = 0;                        ///< pixels
  RenderMode mode = RenderMode::kFaces;  ///< as RenderOptions::mode
  Eigen::Matrix4f view_projection;       ///< world (m) to clip space
  Eigen::Vector3f eye;                   ///< m, for lighting
  Rgba background;                       ///< the clear colour
  std::vector<float> blade_quad;         ///< two triangles, 18 floats; empty without a blade
  std::vector<float> lines;              ///< 6 floats per segment
  std::vector<float> cut_lines;          ///< 6 floats per segment, drawn in a second colour
  bool colour_mapped = false;            ///< the surface's texture is the colour map
  /// Skip back faces (llvmpipe shades every fragment it is given: about a third of the time
  /// of a large body's picture went to faces hidden behind others).
  bool cull_back_faces = false;
};

/// What draws: takes the surface's buffers when they change, the positions every frame, and
/// a draw call (OpenGL in GlBackend; NullBackend records for tests).
class RenderBackend {
 public:
  RenderBackend() = default;
  RenderBackend(const RenderBackend&) = delete;
  RenderBackend& operator=(const RenderBackend&) = delete;
  virtual ~RenderBackend() = default;
  /// A new surface: its vertices, triangles and texture coordinates.
  virtual void upload_surface(const SurfaceBuffers& buffers) = 0;
  /// The buffer vertices' current positions, 3 floats each (m).
  virtual void upload_positions(std::span<const float> xyz) = 0;
  /// Draws one frame of what was uploaded.
  virtual void draw(const DrawCall& call) = 0;
};

/// Records what it was given: for tests on machines without OpenGL.
class NullBackend final : public RenderBackend {
 public:
  void upload_surface(const SurfaceBuffers& buffers) override {
    ++surface_uploads;
    surface = buffers;
  }
  void upload_positions(std::span<const float> xyz) override {
    ++position_uploads;
    positions.assign(xyz.begin(), xyz.end());
  }
  void draw(const DrawCall& call) override {
    ++draws;
    last_call = call;
  }
  int surface_uploads = 0;       ///< upload_surface calls
  int position_uploads = 0;      ///< upload_positions calls
  int draws = 0;                 ///< draw calls
  SurfaceBuffers surface;        ///< the last surface
  std::vector<float> positions;  ///< the last positions
  DrawCall last_call;            ///< the last draw call
};

/// Turns a frame's RenderInput into backend calls, building the surface's buffers again only
/// when its revision (or what it needs) changes. One thread; the backend must outlive it.
class Renderer {
 public:
  /// Draws through `backend`.
  explicit Renderer(RenderBackend& backend) : backend_(&backend) {}
  /// Draws one frame through the backend.
  void render(const RenderInput& input, const RenderOptions& options);

 private:
  RenderBackend* backend_;
  bool uploaded_ = false;
  double uploaded_period_ = 0.0;
  std::array<double, 2> uploaded_range_{};
  SurfaceBuffers buffers_;
  std::vector<float> positions_;
};

/// Anything that turns a frame into a picture (the offscreen OpenGL renderer; fakes in tests).
class ImageRenderer {
 public:
  ImageRenderer() = default;
  ImageRenderer(const ImageRenderer&) = delete;
  ImageRenderer& operator=(const ImageRenderer&) = delete;
  virtual ~ImageRenderer() = default;
  /// The frame as a picture of options.width x options.height.
  [[nodiscard]] virtual Image render(const RenderInput& input, const RenderOptions& options) = 0;
};

/// The box around the current positions of every vertex a triangle uses.
[[nodiscard]] Bounds surface_bounds(std::span<const Triangle> triangles,
                                    std::span<const Vec3> positions);

}  // namespace incise
