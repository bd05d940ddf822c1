#pragma once
// The engine's parts, shared by its frame loop (engine.cpp) and its checkpoints
// (checkpoint.cpp). Private to the engine module.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "incise/cut/subdivision_cutter.hpp"
#include "incise/engine/engine.hpp"
#include "incise/physics/boundary_conditions.hpp"
#include "incise/physics/force_model.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"
#include "incise/xfem/visual_surface.hpp"
#include "incise/xfem/xfem_cutter.hpp"

namespace incise {

struct Engine::Parts {
  explicit Parts(const SceneDescription& scene);

  SceneDescription description;
  TetMesh mesh;
  std::unique_ptr<ForceModel> model;
  BoundaryConditions conditions;
  MechanicalSystem system;
  SimulationState state;
  std::unique_ptr<Integrator> integrator;
  std::unique_ptr<SubdivisionCutter> cutter;
  std::unique_ptr<XfemCutter> xfem;       ///< the scene's cutter when it is xfem (then no `cutter`)
  std::unique_ptr<VisualSurface> visual;  ///< the scene's embedded surface, if any
  std::unique_ptr<VisualSurface> collision;       ///< the scene's collision surface, if any
  std::vector<std::pair<VertexId, Vec3>> pushes;  ///< N, for the next step only
  std::unique_ptr<ToolPoseSource> tool;
  std::optional<BladePose> blade;                      ///< as the tool gave it (drawn there)
  std::vector<std::optional<BladePose>> blade_passed;  ///< the last frame's ToolMotion::passed
  PoseFrame blade_frame = PoseFrame::kRest;
  std::optional<BladePose> blade_rest;  ///< what the cutter was given: in the rest frame
  RestMap rest_map;  ///< the last world-to-rest map around the blade (held while it is outside)
  /// The blade where the body is now (drawn there) and the frame it was computed for: computed
  /// on demand, reset whenever the blade changes.
  mutable std::optional<std::pair<int, std::optional<BladePose>>> blade_world;
  std::vector<FrameSink*> sinks;
  std::vector<std::string> warnings;
  double limit = 0.0;
  double body_size = 0.0;  ///< m: the rest bounding box's diagonal
  int steps_per_frame = 1;
  FrameRecord last;
  bool diverged = false;
  std::string divergence;
  bool publishing = false;
  SnapshotChannel channel;
  std::shared_ptr<const SurfaceTopology> surface;
  std::size_t surface_moves = 0;  ///< cutter moves when `surface` was built

  std::shared_ptr<const SurfaceTopology> visual_topology;  ///< of `visual`, per its revision

  std::string measure(FrameRecord& record) const;
  /// `pose` in the rest frame: as it is, or carried back from the world by the deformation
  /// around the blade (pose_frames.hpp; the map is kept while the blade is outside the body).
  BladePose rest_pose(const BladePose& pose, PoseFrame frame);
  /// The last frame's blade where the body is now.
  const std::optional<BladePose>& world_blade() const;
  /// The visual surface as render topology, rebuilt only when it changed (null without one).
  const std::shared_ptr<const SurfaceTopology>& current_visual_surface();
  /// The boundary with its cut faces marked, rebuilt only when the mesh or the cut changed.
  const std::shared_ptr<const SurfaceTopology>& current_surface();
  void publish();
};

}  // namespace incise
