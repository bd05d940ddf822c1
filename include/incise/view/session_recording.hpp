#pragma once
// A viewer session as the physics saw it, to replay without a window: for each (re)start,
// the scene it ran and, frame by frame, the blade pose the engine took (or none: the tool
// lifted), plus the UI actions with their frame numbers. `incise run --replay FILE` rebuilds
// the last segment's engine and feeds it the same poses: the same final mesh, bit for bit.
//
// File format: JSON lines. The first line is {"incise_session": 1}; then for each segment a
// {"frame": 0, "start": {"scene_file": PATH, "scene": TEXT}} line, and lines
// {"frame": N, "pose": [t, tip_x, tip_y, tip_z, base_x, base_y, base_z]} (s, m; with
// "world": true where the pose is where the body is now, the mouse's, not in its rest frame),
// {"frame": N, "lift": true} and {"frame": N, "action": NAME, "value": TEXT}. A pose or lift
// line may carry "through": [POSE or null, ...], the strokes' ends the blade passed during
// that frame before it (ToolMotion::passed; null: a lift), in the same frame as the pose.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "incise/engine/engine.hpp"

namespace incise {

/// Something the user did in the window (a button, a key) at a frame.
struct SessionAction {
  int frame = 0;      ///< the engine's frame when it was done
  std::string name;   ///< play, pause, step, mode, highlight, screenshot, ...
  std::string value;  ///< its argument, if any (a mode's name, a file)
};

/// One engine's run in a session: its scene and the blade's pose at each frame (a reset in the
/// window starts another segment).
struct SessionSegment {
  std::filesystem::path scene_file;             ///< empty: the built-in default scene
  std::string scene_text;                       ///< the scene's JSON as it was run
  std::vector<std::optional<BladePose>> poses;  ///< index: frame (0: the start)
  std::vector<std::uint8_t> world;              ///< per frame: the pose is in the world
  /// Per frame (may be shorter than poses: none after it): ToolMotion::passed.
  std::vector<std::vector<std::optional<BladePose>>> passed;
  std::vector<SessionAction> actions;  ///< in the order they were done
  /// The scene, parsed as it was run (relative paths against scene_file's folder).
  [[nodiscard]] SceneDescription scene() const;
  [[nodiscard]] int frames() const { return static_cast<int>(poses.size()) - 1; }  ///< stepped
};

/// A viewer session, which `incise run --replay` and `incise view --replay` play bit for bit.
struct SessionRecording {
  std::vector<SessionSegment> segments;  ///< in the order they ran
};

/// Writes atomically; errors name the file.
void write_session(const std::filesystem::path& path, const SessionRecording& recording);
/// Errors name the file and line.
[[nodiscard]] SessionRecording read_session(const std::filesystem::path& path);

/// Records a segment of `recording` from the engine it is added to: the scene, the start pose
/// and each frame's pose. Add one to each engine the viewer makes (a reset starts another).
class SessionRecorder final : public FrameSink {
 public:
  /// Adds to `recording`, which must outlive the recorder.
  explicit SessionRecorder(SessionRecording& recording) : recording_(&recording) {}
  void begin(const Engine& engine) override;
  bool frame(const Engine& engine, const FrameRecord& record) override;
  /// A UI action at the engine's current frame.
  void action(int frame, std::string name, std::string value = {});

 private:
  SessionRecording* recording_;
};

/// The poses of a recorded segment, frame by frame; the tool is lifted after its end.
class RecordedToolPoses final : public ToolPoseSource {
 public:
  /// `world` per frame (empty: every pose in the rest frame); `passed` per frame (may be
  /// shorter: none after it).
  RecordedToolPoses(std::vector<std::optional<BladePose>> poses, std::vector<std::uint8_t> world,
                    std::vector<std::vector<std::optional<BladePose>>> passed = {})
      : poses_(std::move(poses)), world_(std::move(world)), passed_(std::move(passed)) {}
  [[nodiscard]] std::optional<BladePose> pose(int frame, double time) override;
  [[nodiscard]] ToolMotion motion(int frame, double time) override;
  [[nodiscard]] PoseFrame frame() const override { return frame_; }

 private:
  std::vector<std::optional<BladePose>> poses_;
  std::vector<std::uint8_t> world_;
  std::vector<std::vector<std::optional<BladePose>>> passed_;
  PoseFrame frame_ = PoseFrame::kRest;
};

/// The scene as the viewer runs it: with a cutter even where the scene has none (the mouse
/// cuts any scene).
[[nodiscard]] SceneDescription viewer_scene(SceneDescription scene);

/// An engine that replays `segment`: its scene, fed its poses (run segment.frames() frames).
[[nodiscard]] std::unique_ptr<Engine> replay_engine(const SessionSegment& segment);

}  // namespace incise
