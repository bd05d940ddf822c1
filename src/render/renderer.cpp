#include "incise/render/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"

namespace incise {

namespace {

constexpr std::array<std::pair<RenderMode, std::string_view>, 3> kModeNames{{
    {RenderMode::kFaces, "faces"},
    {RenderMode::kWire, "wire"},
    {RenderMode::kCut, "cut"},
}};

void push(std::vector<float>& out, const Vec3& p) {
  out.push_back(static_cast<float>(p.x()));
  out.push_back(static_cast<float>(p.y()));
  out.push_back(static_cast<float>(p.z()));
}

/// The blade as a ribbon facing the camera: the segment widened across the view.
std::vector<float> blade_ribbon(const std::array<Vec3, 2>& blade, const Vec3& eye, double width) {
  const Vec3& tip = blade[0];
  const Vec3& base = blade[1];
  const Vec3 along = base - tip;
  Vec3 across = along.cross(0.5 * (tip + base) - eye);
  if (across.norm() < 1e-12 || along.norm() < 1e-12) {
    return {};  // seen end-on, or no length: nothing to draw
  }
  across = 0.5 * width * across.normalized();
  std::vector<float> quad;
  for (const Vec3& p : {Vec3(tip - across), Vec3(base - across), Vec3(base + across),
                        Vec3(tip - across), Vec3(base + across), Vec3(tip + across)}) {
    push(quad, p);
  }
  return quad;
}

}  // namespace

std::string_view name_of(RenderMode mode) {
  for (const auto& [value, name] : kModeNames) {
    if (value == mode) {
      return name;
    }
  }
  return "?";
}

std::optional<RenderMode> parse_render_mode(std::string_view name) {
  for (const auto& [value, known] : kModeNames) {
    if (known == name) {
      return value;
    }
  }
  return std::nullopt;
}

bool closed_and_facing_out(std::span<const Triangle> triangles, std::span<const Vec3> positions) {
  return !triangles.empty() && is_watertight(triangles) &&
         enclosed_volume(positions, triangles) > 0.0;
}

SurfaceBuffers build_surface_buffers(const RenderInput& input, double texture_period,
                                     std::array<double, 2> scalar_range) {
  INCISE_ASSERT(input.on_cut.size() == input.triangles.size(), "one cut mark per triangle");
  INCISE_ASSERT(texture_period > 0.0, "texture period must be positive");
  SurfaceBuffers buffers;
  buffers.revision = input.surface_revision;
  buffers.colour_mapped = !input.scalars.empty();
  const double span = scalar_range[1] - scalar_range[0];
  const std::size_t vertex_count = input.positions.size();
  std::vector<std::uint32_t> slot(vertex_count, ~std::uint32_t{0});
  const auto slot_of = [&](std::size_t triangle, VertexId v) {
    if (v < 0 || static_cast<std::size_t>(v) >= vertex_count ||
        static_cast<std::size_t>(v) >= input.rest_positions.size()) {
      throw InputError("surface triangle " + std::to_string(triangle) + " refers to vertex " +
                       std::to_string(v) + ", which has no position");
    }
    auto& s = slot[static_cast<std::size_t>(v)];
    if (s == ~std::uint32_t{0}) {
      const Vec3& rest = input.rest_positions[static_cast<std::size_t>(v)];
      if (!rest.allFinite()) {
        throw InputError("vertex " + std::to_string(v) + " has no finite rest position");
      }
      s = static_cast<std::uint32_t>(buffers.vertices.size());
      buffers.vertices.push_back(v);
      if (buffers.colour_mapped) {
        if (static_cast<std::size_t>(v) >= input.scalars.size()) {
          throw InputError("surface triangle " + std::to_string(triangle) + " refers to vertex " +
                           std::to_string(v) + ", which has no scalar");
        }
        const double value = input.scalars[static_cast<std::size_t>(v)];
        const double t = span > 0.0 ? (value - scalar_range[0]) / span : 0.5;
        push(buffers.texture_coordinates,
             Vec3(std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0, 0.5, 0.5));
      } else {
        // Texture coordinates in tiles of the solid texture (it repeats).
        push(buffers.texture_coordinates, rest / texture_period);
      }
    }
    return s;
  };
  for (int pass = 0; pass < 2; ++pass) {
    const std::uint8_t wanted = pass == 0 ? 0 : 1;
    for (std::size_t t = 0; t < input.triangles.size(); ++t) {
      if ((input.on_cut[t] != 0 ? 1 : 0) != wanted) {
        continue;
      }
      for (VertexId v : input.triangles[t]) {
        buffers.indices.push_back(slot_of(t, v));
      }
      ++(pass == 0 ? buffers.exterior_triangles : buffers.cut_triangles);
    }
  }
  // Slots were checked above: every triangle's vertices have finite rest positions.
  for (VertexId v : buffers.vertices) {
    buffers.positions_needed = std::max(buffers.positions_needed, static_cast<std::size_t>(v) + 1);
  }
  buffers.closed_outward = closed_and_facing_out(input.triangles, input.rest_positions);
  return buffers;
}

void gather_positions(const SurfaceBuffers& buffers, std::span<const Vec3> positions,
                      std::vector<float>& out) {
  out.clear();
  out.reserve(3 * buffers.vertices.size());
  for (VertexId v : buffers.vertices) {
    push(out, positions[static_cast<std::size_t>(v)]);
  }
}

Bounds surface_bounds(std::span<const Triangle> triangles, std::span<const Vec3> positions) {
  Bounds box;
  for (const Triangle& triangle : triangles) {
    for (VertexId v : triangle) {
      box.add(positions[static_cast<std::size_t>(v)]);
    }
  }
  return box;
}

void Renderer::render(const RenderInput& input, const RenderOptions& options) {
  // Built again when the surface changed, and when this frame's positions do not reach every
  // vertex of the buffers in hand (a caller that changed the surface under the same revision:
  // reading on would be out of bounds).
  if (!uploaded_ || buffers_.revision != input.surface_revision ||
      input.positions.size() < buffers_.positions_needed ||
      uploaded_period_ != options.texture_period ||
      buffers_.colour_mapped != !input.scalars.empty() ||
      (buffers_.colour_mapped && uploaded_range_ != options.scalar_range)) {
    buffers_ = build_surface_buffers(input, options.texture_period, options.scalar_range);
    backend_->upload_surface(buffers_);
    uploaded_ = true;
    uploaded_period_ = options.texture_period;
    uploaded_range_ = options.scalar_range;
  }
  // The surface's box from its own vertices, each once.
  Bounds scene;
  for (VertexId v : buffers_.vertices) {
    const Vec3& p = input.positions[static_cast<std::size_t>(v)];
    if (!p.allFinite()) {
      throw InputError("surface vertex " + std::to_string(v) +
                       " has no finite position: nothing to draw");
    }
    scene.add(p);
  }
  gather_positions(buffers_, input.positions, positions_);
  backend_->upload_positions(positions_);

  if (input.blade) {
    scene.add((*input.blade)[0]);
    scene.add((*input.blade)[1]);
  }
  if (scene.empty()) {
    scene.add(options.camera.target);
  }
  DrawCall call;
  call.width = options.width;
  call.height = options.height;
  call.mode = options.mode;
  const double aspect = static_cast<double>(options.width) / options.height;
  call.view_projection =
      (projection_matrix(options.camera, aspect, scene) * view_matrix(options.camera))
          .cast<float>();
  call.eye = options.camera.eye.cast<float>();
  call.background = options.background;
  call.colour_mapped = buffers_.colour_mapped;
  // Cut mode shows the wound's faces alone, an open surface seen from both sides.
  call.cull_back_faces =
      buffers_.closed_outward && !options.two_sided && options.mode != RenderMode::kCut;
  if (options.draw_blade && input.blade) {
    call.blade_quad = blade_ribbon(*input.blade, options.camera.eye, 0.02 * scene.radius());
  }
  for (const auto& segment : input.highlights) {
    push(call.lines, segment[0]);
    push(call.lines, segment[1]);
  }
  for (const auto& segment : input.cut_edges) {
    push(call.cut_lines, segment[0]);
    push(call.cut_lines, segment[1]);
  }
  backend_->draw(call);
}

}  // namespace incise
