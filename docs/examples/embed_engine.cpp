// incise in your own program: the default scene stepped by your loop, the blade set as a
// tracked device would set it (LiveToolPose::set may be called from any thread), and a sink of
// your own told of every frame. Units: m, s.
#include <cstdio>
#include <incise/engine/engine.hpp>
#include <memory>

namespace {

/// Prints each frame in which the cut advanced (called on the engine's thread).
class CutLog final : public incise::FrameSink {
 public:
  bool frame(const incise::Engine& /*engine*/, const incise::FrameRecord& record) override {
    if (record.edited) {
      std::printf("frame %d: %zu tetrahedra, cd %.2f ms, gc %.2f ms\n", record.frame, record.tets,
                  1e3 * record.cd, 1e3 * record.gc);
    }
    return false;  // it wrote no file
  }
};

}  // namespace

int main() {
  incise::Engine engine(incise::default_scene());        // or incise::load_scene("scene.json")
  auto live = std::make_unique<incise::LiveToolPose>();  // poses in the body's rest frame
  incise::LiveToolPose& blade = *live;
  engine.set_tool_source(std::move(live));
  CutLog log;
  engine.add_sink(log);
  for (int frame = 0; frame < 100; ++frame) {
    const double y = -0.012 + 0.084 * frame / 99.0;  // across the 6 cm block, 1.2 cm deep
    blade.set({0.0, incise::Vec3(0.0213, y, 0.012), incise::Vec3(0.0213, y, 0.06)});
    if (!engine.step()) {
      std::printf("diverged: %s\n", engine.divergence().c_str());
      return 1;
    }
  }
  engine.finish();
  std::printf("%zu tetrahedra after the cut\n", engine.mesh().tet_count());
  return engine.mesh().tet_count() > 576 ? 0 : 1;
}
