#pragma once
// Where the scalpel is: the engine asks a ToolPoseSource for the blade pose at the end of each
// frame. Sources: a scripted or recorded path (poses over time, interpolated), and a live pose
// set from another thread (the viewer's mouse, a network device).
//
// A live source is sampled at the physics' frame rate, which a loaded machine may drop to a few
// frames per second while a device sends 1,000 poses per second. So that what is cut does not
// depend on when the physics looked, a frame also gets the stroke's ends that fell between two
// frames (ToolMotion::passed): where a stroke began and where it was lifted. Between them the
// blade sweeps straight from one frame's pose to the next, as it does for a scripted path.

#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "incise/cut/blade.hpp"
#include "incise/engine/pose_frames.hpp"

namespace incise {

/// What the tool did over one frame, in the frame of ToolPoseSource::frame().
struct ToolMotion {
  /// Poses it passed through since the last frame, in order, before `pose`; an empty entry is a
  /// lift (the stroke ended just before it).
  std::vector<std::optional<BladePose>> passed;
  /// Where it is at the end of the frame; nothing while it is away from the body.
  std::optional<BladePose> pose;
};

/// Where the blade is, frame by frame: the engine asks once per frame (Engine::set_tool_source).
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
  /// The frame's motion: what the engine cuts with at each step. Default: pose() alone, for a
  /// path that is the same whenever it is sampled.
  [[nodiscard]] virtual ToolMotion motion(int frame, double time) {
    return {{}, pose(frame, time)};
  }
  /// The frame of the pose pose() returned last: the body's rest frame (scene and recorded
  /// paths, the default) or the world, where the body is now (a mouse, a tracked device).
  [[nodiscard]] virtual PoseFrame frame() const { return PoseFrame::kRest; }
};

/// A path of poses over time, linearly interpolated and held at its ends: the scene's
/// scripted path, or a recorded one replayed (`from_csv`).
class ScriptedToolPath final : public ToolPoseSource {
 public:
  /// Poses in time order (their `time` in s).
  explicit ScriptedToolPath(std::vector<BladePose> poses);
  /// A blade-path CSV (t,tip_x,tip_y,tip_z,base_x,base_y,base_z; s, m), as `incise cut` reads
  /// and ToolPathRecorder writes.
  [[nodiscard]] static std::unique_ptr<ScriptedToolPath> from_csv(
      const std::filesystem::path& path);
  [[nodiscard]] std::optional<BladePose> pose(int frame, double time) override;
  [[nodiscard]] const std::vector<BladePose>& poses() const { return poses_; }  ///< the path

 private:
  std::vector<BladePose> poses_;
};

/// The latest pose set by another thread (a viewer, a device loop), with the ends of the
/// strokes that began or ended since the engine last read it. Thread rule: set() and lift() may
/// be called from any thread at any rate; the engine reads once per frame under a lock held
/// only to move the poses out.
class LiveToolPose final : public ToolPoseSource {
 public:
  /// Poses set in `frame`: kWorld for a mouse on the picture or a tracked device.
  explicit LiveToolPose(PoseFrame frame = PoseFrame::kRest) : frame_(frame) {}
  /// The blade is at `pose` (its time is ignored: the engine stamps its own).
  void set(const BladePose& pose);
  /// The blade leaves the body: the next set() starts a new stroke.
  void lift();
  /// The newest pose, leaving the strokes' ends for motion().
  [[nodiscard]] std::optional<BladePose> pose(int frame, double time) override;
  /// The strokes' ends since the last call, then the newest pose; all stamped `time`.
  [[nodiscard]] ToolMotion motion(int frame, double time) override;
  /// Whether strokes' ends wait for the next motion(): a device that left between two frames
  /// still has its last stroke's end to cut.
  [[nodiscard]] bool has_passed();
  [[nodiscard]] PoseFrame frame() const override { return frame_; }

  /// At most this many strokes' ends are kept between two frames (the oldest go first): a
  /// stalled engine holds bounded memory however a device flickers.
  static constexpr std::size_t kMaxPassed = 64;

 private:
  PoseFrame frame_;
  std::mutex mutex_;
  std::optional<BladePose> pose_;
  std::optional<BladePose> read_;  ///< the pose motion() returned last
  std::vector<std::optional<BladePose>> passed_;
};

}  // namespace incise
