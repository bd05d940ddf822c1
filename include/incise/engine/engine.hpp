#pragma once
// The engine: a scene you step one frame at a time (the seed's Fig. 1 loop: tool pose,
// collision detection, topology and geometry changes, relaxation, output), fed by a
// ToolPoseSource and watched through FrameSinks and published Snapshots.
//
// Thread rule: one thread owns the engine and calls every member function. Other threads (a
// viewer, a 1 kHz device loop) touch only (a) snapshots(): take latest() at any time, never
// blocking step(); (b) a LiveToolPose they were given, through set() and lift(). Nothing
// else, mesh() and state() included, may be read while step() runs.

#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "incise/engine/frame_sink.hpp"
#include "incise/engine/snapshot.hpp"
#include "incise/engine/tool_pose_source.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/scene/scene.hpp"

namespace incise {

class SubdivisionCutter;
class XfemCutter;
class VisualSurface;
class Integrator;

/// One frame: stage times (s) named after the seed's Table 1, and the state after it.
struct FrameRecord {
  int frame = 0;                      ///< frame number, from 1
  double time = 0.0;                  ///< simulated time at the end of the frame (s)
  double cd = 0.0;                    ///< collision detection (s)
  double gc = 0.0;                    ///< topology and geometry changes (s)
  double rx = 0.0;                    ///< relaxation (s)
  double rd = 0.0;                    ///< output: sinks and the published snapshot (s)
  std::size_t solver_iterations = 0;  ///< the solver's iterations in the frame (0: explicit)
  /// Where rx went (s), summed over the frame's steps (IntegratorStats): the model following
  /// the mesh's edits, forces with the linearisation, the system matrix and preconditioner,
  /// the solver's starting guess, its products and its vector updates. Implicit schemes only.
  struct RelaxationParts {
    double refresh = 0.0;         ///< the model following the mesh's edits (s)
    double forces = 0.0;          ///< forces and their linearisation (s)
    double preconditioner = 0.0;  ///< the system matrix and the preconditioner (s)
    double start = 0.0;           ///< the solver's starting guess (s)
    double products = 0.0;        ///< matrix-vector products (s)
    double vector_updates = 0.0;  ///< the solver's vector updates and dot products (s)
  } rx_parts;                     ///< where rx went
  std::size_t vertices = 0;       ///< vertices after the frame
  std::size_t tets = 0;           ///< tetrahedra after the frame
  double kinetic_energy = 0.0;    ///< J
  double max_displacement = 0.0;  ///< m, from the rest position
  bool written = false;           ///< a sink wrote output for this frame
  bool cut = false;               ///< the blade moved (with a cutter) this frame
  bool edited = false;            ///< the mesh changed this frame (the cut advanced)
};

/// A scene stepped frame by frame: the tool moves (cd, gc: the cutters edit the mesh), the
/// body relaxes (rx), the frame sinks write and a snapshot is published (rd). Not thread-safe:
/// one thread steps it; other threads read the snapshots() channel only.
class Engine {
 public:
  /// Builds the body, models, integrator, cutters and tool source the scene describes.
  /// Throws InputError naming the key when the scene cannot be built.
  explicit Engine(const SceneDescription& scene);
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  /// Replaces the tool's pose source (the scene's scripted path by default; none without a
  /// tool). A cutter is needed to cut: the scene's `cutter`.
  void set_tool_source(std::unique_ptr<ToolPoseSource> source);
  /// Adds an output; it sees the current state at once (begin) and every frame from now on.
  /// The engine does not own it: it must outlive the engine or finish().
  void add_sink(FrameSink& sink);
  /// Publish a snapshot after every frame (and now) for other threads: off by default, as it
  /// copies the positions every frame and the boundary after every cut.
  void publish_snapshots(bool enabled);

  /// Advances one frame. Returns false when it diverged: the state is then that frame's
  /// (not handed to sinks), divergence() says what went wrong, and step() does nothing more.
  bool step();
  /// Ends the run: every sink's end() (a series writes its last frame).
  void finish();

  /// Writes the complete state to `path`, atomically (a temporary renamed over it): the scene
  /// it was built from, the mesh with every attribute and label, positions and velocities,
  /// the integrator's history, the cutter's state, the scripted tool path, time and frame.
  /// A run resumed from it writes the same frames, bit for bit, as one that never stopped.
  void save_checkpoint(const std::filesystem::path& path) const;
  /// An engine that continues a checkpointed run: the stored scene built afresh, then every
  /// part's state restored. A missing, truncated, corrupted or foreign file is an InputError
  /// naming it; nothing is half-restored.
  [[nodiscard]] static std::unique_ptr<Engine> resume(const std::filesystem::path& path);
  /// The same state as bytes in memory (what save_checkpoint writes), e.g. to reset an episode.
  [[nodiscard]] std::string save_state() const;
  /// An engine continuing from save_state()'s bytes (as resume() from a file); `name` names
  /// them in errors. Bad bytes are an InputError; nothing is half-restored.
  [[nodiscard]] static std::unique_ptr<Engine> restore_state(std::string_view bytes,
                                                             const std::string& name);
  /// A checkpoint file holding `state` (the bytes after the header) under a valid header: its
  /// format version, size and checksum. For fuzzing the state itself, which the checksum
  /// otherwise shields from random changes.
  [[nodiscard]] static std::string checkpoint_with_state(std::string_view state);

  [[nodiscard]] int frame() const;                      ///< frames stepped so far
  [[nodiscard]] double time() const;                    ///< s
  [[nodiscard]] const FrameRecord& last_frame() const;  ///< the record of the last frame
  /// Whether the simulation diverged (then step() refuses to go on).
  [[nodiscard]] bool diverged() const;
  /// What diverged, and where (empty while it has not).
  [[nodiscard]] const std::string& divergence() const;

  [[nodiscard]] const SceneDescription& scene() const;  ///< the scene as it was built
  [[nodiscard]] const TetMesh& mesh() const;            ///< the body's mesh, cut as far as it is
  /// Positions and velocities (m, m/s) and the simulated time.
  [[nodiscard]] const SimulationState& state() const;
  [[nodiscard]] std::span<const Vec3> positions() const;  ///< current (m)
  /// The subdivision cutter, or null when the scene has none: its cut faces are the cut
  /// surface.
  [[nodiscard]] const SubdivisionCutter* cutter() const;
  /// The XFEM cutter (scene `cutter: {"type": "xfem"}`), or null.
  [[nodiscard]] const XfemCutter* xfem_cutter() const;
  /// The embedded visual surface (scene `visual`), or null; its positions() follow positions().
  [[nodiscard]] const VisualSurface* visual() const;
  /// The visual surface as render topology (rest positions: the surface's points), rebuilt
  /// when it changes; null without one.
  [[nodiscard]] std::shared_ptr<const SurfaceTopology> visual_surface() const;
  /// Where contact acts: the collision surface (scene `collision`), else the visual one, else
  /// null.
  [[nodiscard]] const VisualSurface* collision() const;
  /// Pushes on the body during the next step only: a force (N) at a point of a collision
  /// triangle (barycentric coordinates), spread over the physics nodes that carry that point,
  /// so on a cut body it moves the piece the point lies on (virtual elements' own nodes).
  void push(std::size_t triangle, const std::array<double, 3>& barycentric, const Vec3& force);
  /// The boundary triangles that lie on a cut (outward, vertex ids), empty without a cutter.
  [[nodiscard]] std::vector<Triangle> cut_surface() const;
  /// The boundary surface with its cut faces marked and the rest positions (the one the
  /// snapshots publish), built once per mesh revision and cutter move.
  [[nodiscard]] std::shared_ptr<const SurfaceTopology> surface() const;
  /// The blade at the end of the last frame, if the tool was on, as its source gave it (in
  /// blade_frame(): the world for a mouse or device, else the rest frame).
  [[nodiscard]] const std::optional<BladePose>& blade() const;
  /// The strokes' ends the blade passed through during the last frame, before blade(), in the
  /// same frame (ToolMotion::passed; empty but for a live source between two frames).
  [[nodiscard]] const std::vector<std::optional<BladePose>>& blade_passed() const;
  [[nodiscard]] PoseFrame blade_frame() const;  ///< the frame blade() is given in
  /// The same blade in the body's rest frame: what the cutter cut with.
  [[nodiscard]] const std::optional<BladePose>& blade_rest() const;
  /// The same blade where the body is now (a rest-frame pose carried by the deformation around
  /// it): where pictures and snapshots draw it. Computed on first use per frame, so the
  /// engine's thread only (other threads take the snapshot's).
  [[nodiscard]] const std::optional<BladePose>& blade_world() const;
  [[nodiscard]] const Integrator& integrator() const;  ///< with its last step's statistics
  /// The materials of the body (table and one per tetrahedron), or null if the model keeps none.
  [[nodiscard]] const MaterialMap* materials() const;
  [[nodiscard]] double total_mass() const;  ///< kg
  /// Tetrahedra the inversion guard (model.inversion_guard) pushed back right side out, summed
  /// over the steps so far, and the most in one step.
  [[nodiscard]] std::uint64_t guarded_tets() const;
  [[nodiscard]] std::size_t guarded_tets_most() const;  ///< the most in one step
  /// Vertices its fallback moved back towards the start of their step: summed, most in a step.
  [[nodiscard]] std::uint64_t backtracked_vertices() const;
  [[nodiscard]] std::size_t backtracked_vertices_most() const;  ///< the most in one step
  /// The integrator's largest stable step on this scene (s; infinity for implicit schemes).
  [[nodiscard]] double stability_limit() const;
  /// Warnings about the scene (e.g. a step beyond the stability limit).
  [[nodiscard]] const std::vector<std::string>& warnings() const;
  /// Where each frame's snapshot is published: what another thread (a window, a server) may
  /// read while this one steps.
  [[nodiscard]] const SnapshotChannel& snapshots() const;

 private:
  struct Parts;
  std::unique_ptr<Parts> parts_;
};

/// Writes a checkpoint every `every` frames and when the run ends (unless it diverged).
class CheckpointSink final : public FrameSink {
 public:
  /// Checkpoints go to `path` (written atomically), every `every` frames.
  CheckpointSink(std::filesystem::path path, int every);
  bool frame(const Engine& engine, const FrameRecord& record) override;
  void end(const Engine& engine) override;

 private:
  std::filesystem::path path_;
  int every_;
  int written_frame_ = -1;
};

/// Frames run by run(): each frame's record, and how it ended.
struct RunResult {
  std::vector<FrameRecord> frames;  ///< one record per frame run
  bool diverged = false;            ///< the run stopped at a divergence
  std::string divergence;           ///< what diverged (empty otherwise)
};

/// Steps `frames` frames (stopping at a divergence), calling `on_frame` after each, then
/// finish().
RunResult run(Engine& engine, int frames,
              const std::function<void(const FrameRecord&)>& on_frame = {});

}  // namespace incise
