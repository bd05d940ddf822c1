#include "incise/view/frame_scene.hpp"

#include "incise/cut/subdivision_cutter.hpp"
#include "incise/xfem/visual_surface.hpp"

namespace incise {

namespace {

std::array<Vec3, 2> segment(const BladePose& pose) {
  return {pose.tip, pose.base};
}

}  // namespace

RenderInput FrameScene::input() const {
  RenderInput input;
  input.surface_revision = surface->version;
  input.triangles = surface->triangles;
  input.on_cut = surface->on_cut;
  input.rest_positions = surface->rest_positions;
  input.positions = positions;
  input.blade = blade;
  input.highlights = highlights;
  input.cut_edges = cut_edges;
  return input;
}

Bounds FrameScene::bounds() const {
  return surface_bounds(surface->triangles, positions);
}

FrameScene frame_scene(const Engine& engine, bool highlight_active) {
  FrameScene scene;
  scene.surface = engine.surface();
  scene.positions = engine.positions();
  if (engine.blade_world()) {
    scene.blade = segment(*engine.blade_world());
  }
  if (engine.visual() != nullptr) {
    // The visual surface is what a user sees; highlights still follow the physics mesh.
    scene.surface = engine.visual_surface();
    scene.owned =
        std::make_shared<const std::vector<Vec3>>(engine.visual()->positions(engine.positions()));
    scene.positions = *scene.owned;
    highlight_active = false;
  }
  if (highlight_active && engine.cutter() != nullptr) {
    const TetMesh& mesh = engine.mesh();
    for (TetId tet : engine.cutter()->active_tets()) {
      const Tet& v = mesh.tet(tet);
      for (int a = 0; a < 4; ++a) {
        for (int b = a + 1; b < 4; ++b) {
          const std::array<Vec3, 2> edge{scene.positions[static_cast<std::size_t>(v[a])],
                                         scene.positions[static_cast<std::size_t>(v[b])]};
          const bool cut = engine.cutter()->on_cut(v[a]) && engine.cutter()->on_cut(v[b]);
          (cut ? scene.cut_edges : scene.highlights).push_back(edge);
        }
      }
    }
  }
  return scene;
}

FrameScene frame_scene(std::shared_ptr<const Snapshot> snapshot, bool highlight_active) {
  FrameScene scene;
  scene.surface = snapshot->surface;
  scene.positions = snapshot->positions;
  if (snapshot->blade) {
    scene.blade = segment(*snapshot->blade);
  }
  if (highlight_active) {
    for (const ActiveTet& tet : snapshot->active) {
      for (int a = 0; a < 4; ++a) {
        for (int b = a + 1; b < 4; ++b) {
          const std::array<Vec3, 2> edge{
              scene.positions[static_cast<std::size_t>(tet.vertices[a])],
              scene.positions[static_cast<std::size_t>(tet.vertices[b])]};
          const bool cut = ((tet.on_cut >> a) & 1) != 0 && ((tet.on_cut >> b) & 1) != 0;
          (cut ? scene.cut_edges : scene.highlights).push_back(edge);
        }
      }
    }
  }
  if (snapshot->visual_surface) {
    scene.surface = snapshot->visual_surface;
    scene.positions = snapshot->visual_positions;
  }
  scene.snapshot = std::move(snapshot);
  return scene;
}

Camera scene_camera(const SceneDescription& scene, const Bounds& body, double aspect) {
  if (!scene.camera) {
    return fit_camera(body, aspect);
  }
  Camera camera;
  camera.eye = scene.camera->eye;
  camera.target = scene.camera->target;
  camera.up = scene.camera->up;
  camera.fov_y_degrees = scene.camera->fov_degrees;
  return camera;
}

}  // namespace incise
