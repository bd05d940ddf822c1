#pragma once
// A running scene: the frame loop of the seed's Fig. 1 (collision detection, topology and
// geometry changes, relaxation, output), each stage timed as in the seed's Table 1.

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "incise/io/mesh_io.hpp"
#include "incise/scene/scene.hpp"

namespace incise {

/// One frame: stage times (s) named after the seed's Table 1, and the state after it.
struct FrameRecord {
  int frame = 0;
  double time = 0.0;  ///< simulated time at the end of the frame (s)
  double cd = 0.0;    ///< collision detection (s)
  double gc = 0.0;    ///< topology and geometry changes (s)
  double rx = 0.0;    ///< relaxation (s)
  double rd = 0.0;    ///< rendering / output (s)
  std::size_t vertices = 0;
  std::size_t tets = 0;
  double kinetic_energy = 0.0;    ///< J
  double max_displacement = 0.0;  ///< m, from the rest position
  bool written = false;           ///< a .vtu was written for this frame
};

struct RunResult {
  std::vector<FrameRecord> frames;
  bool diverged = false;
  std::string divergence;  ///< what went wrong, when diverged
  std::filesystem::path pvd;
};

class Simulation {
 public:
  explicit Simulation(const SceneDescription& scene);
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  /// Runs `frames` frames, writing every `vtu_every`-th (and the first and last) into
  /// `output_dir` with a .pvd series named `name`. Stops at the first diverging frame, whose
  /// state is not written. `on_frame` is called after each frame.
  RunResult run(int frames, const std::filesystem::path& output_dir, const std::string& name,
                int vtu_every, const std::function<void(const FrameRecord&)>& on_frame = {});

  [[nodiscard]] const TetMesh& mesh() const;
  [[nodiscard]] const SimulationState& state() const;
  [[nodiscard]] const Integrator& integrator() const;
  [[nodiscard]] double total_mass() const;
  /// Estimated largest stable explicit step for this scene (s).
  [[nodiscard]] double stability_limit() const;
  /// Warnings about the scene (e.g. a step beyond the explicit stability limit).
  [[nodiscard]] const std::vector<std::string>& warnings() const;

 private:
  struct Parts;
  std::unique_ptr<Parts> parts_;
};

}  // namespace incise
