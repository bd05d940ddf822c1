#pragma once
// Where the scalpel is: the engine asks a ToolPoseSource for the blade pose at the end of each
// frame. Sources: a scripted or recorded path (poses over time, interpolated), and a live pose
// set from another thread (the viewer's mouse, a network device).

#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "incise/cut/blade.hpp"
#include "incise/engine/pose_frames.hpp"

namespace incise {

class ToolPoseSource {
 public:
  ToolPoseSource() = default;
  ToolPoseSource(const ToolPoseSource&) = delete;
  ToolPoseSource& operator=(const ToolPoseSource&) = delete;
  virtual ~ToolPoseSource() = default;

  /// The blade pose at simulated time `time` (s), the end of frame `frame` (0: the start), or
  /// nothing while the tool is away from the body (a later pose starts a new stroke). Called
  /// from the thread that steps the engine, once per frame.
  [[nodiscard]] virtual std::optional<BladePose> pose(int frame, double time) = 0;
  /// The frame of the pose pose() returned last: the body's rest frame (scene and recorded
  /// paths, the default) or the world, where the body is now (a mouse, a tracked device).
  [[nodiscard]] virtual PoseFrame frame() const { return PoseFrame::kRest; }
};

/// A path of poses over time, linearly interpolated and held at its ends: the scene's
/// scripted path, or a recorded one replayed (`from_csv`).
class ScriptedToolPath final : public ToolPoseSource {
 public:
  explicit ScriptedToolPath(std::vector<BladePose> poses);
  /// A blade-path CSV (t,tip_x,tip_y,tip_z,base_x,base_y,base_z; s, m), as `incise cut` reads
  /// and ToolPathRecorder writes.
  [[nodiscard]] static std::unique_ptr<ScriptedToolPath> from_csv(
      const std::filesystem::path& path);
  [[nodiscard]] std::optional<BladePose> pose(int frame, double time) override;
  [[nodiscard]] const std::vector<BladePose>& poses() const { return poses_; }

 private:
  std::vector<BladePose> poses_;
};

/// The latest pose set by another thread (a viewer, a device loop). Thread rule: set() and
/// lift() may be called from any thread at any rate; the engine reads the newest pose once
/// per frame under a lock held only to copy it.
class LiveToolPose final : public ToolPoseSource {
 public:
  /// Poses set in `frame`: kWorld for a mouse on the picture or a tracked device.
  explicit LiveToolPose(PoseFrame frame = PoseFrame::kRest) : frame_(frame) {}
  /// The blade is at `pose` (its time is ignored: the engine stamps its own).
  void set(const BladePose& pose);
  /// The blade leaves the body: the next set() starts a new stroke.
  void lift();
  [[nodiscard]] std::optional<BladePose> pose(int frame, double time) override;
  [[nodiscard]] PoseFrame frame() const override { return frame_; }

 private:
  PoseFrame frame_;
  std::mutex mutex_;
  std::optional<BladePose> pose_;
};

}  // namespace incise
