#pragma once
// What the renderer draws of a running engine: its boundary surface (cut faces marked, rest
// positions for the solid textures), or its embedded visual surface when the scene has one,
// current positions, the blade and optional highlights, taken either on the engine's thread or
// from a published snapshot on any other.

#include <array>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "incise/engine/engine.hpp"
#include "incise/render/renderer.hpp"

namespace incise {

/// Owns (or shares) everything a RenderInput points to.
struct FrameScene {
  std::shared_ptr<const SurfaceTopology> surface;  ///< the triangles drawn, at rest
  std::span<const Vec3> positions;                 ///< the engine's, `snapshot`'s, or `owned`
  /// Positions computed for this frame (an embedded visual surface's), shared by copies.
  std::shared_ptr<const std::vector<Vec3>> owned;
  std::shared_ptr<const Snapshot> snapshot;     ///< the published frame drawn, if any
  std::optional<std::array<Vec3, 2>> blade;     ///< the blade's tip and base (m), if on
  std::vector<std::array<Vec3, 2>> highlights;  ///< edges outlined (the active tetrahedra)
  std::vector<std::array<Vec3, 2>> cut_edges;   ///< edges drawn along the wound
  /// The render input pointing into this frame (valid while it lives).
  [[nodiscard]] RenderInput input() const;
  /// The box around the surface's current positions (m).
  [[nodiscard]] Bounds bounds() const;
};

/// The engine's current frame; `highlight_active` adds the edges of the cutter's active
/// tetrahedra (the ones the blade is in), and apart those of them on the cut (both ends on
/// it: the edges the blade has cut through). Only on the engine's thread, between steps.
[[nodiscard]] FrameScene frame_scene(const Engine& engine, bool highlight_active = false);
/// A published snapshot: safe on any thread; `highlight_active` as for an engine.
[[nodiscard]] FrameScene frame_scene(std::shared_ptr<const Snapshot> snapshot,
                                     bool highlight_active = false);

/// The scene's camera (its `camera` key), else one fitted to `body` for the given aspect.
[[nodiscard]] Camera scene_camera(const SceneDescription& scene, const Bounds& body, double aspect);

}  // namespace incise
