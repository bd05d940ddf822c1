#include "incise/engine/tool_pose_source.hpp"

#include "incise/core/error.hpp"
#include "incise/scene/scene.hpp"

namespace incise {

ScriptedToolPath::ScriptedToolPath(std::vector<BladePose> poses) : poses_(std::move(poses)) {
  if (poses_.empty()) {
    throw InputError("a scripted tool path needs at least one pose");
  }
}

std::unique_ptr<ScriptedToolPath> ScriptedToolPath::from_csv(const std::filesystem::path& path) {
  std::vector<BladePose> poses = read_blade_path(path);
  if (poses.empty()) {
    throw InputError(path.string(), 0, "the blade path holds no pose");
  }
  return std::make_unique<ScriptedToolPath>(std::move(poses));
}

std::optional<BladePose> ScriptedToolPath::pose(int /*frame*/, double time) {
  return pose_at(poses_, time);
}

void LiveToolPose::set(const BladePose& pose) {
  const std::lock_guard lock(mutex_);
  pose_ = pose;
}

void LiveToolPose::lift() {
  const std::lock_guard lock(mutex_);
  pose_.reset();
}

std::optional<BladePose> LiveToolPose::pose(int /*frame*/, double time) {
  std::optional<BladePose> copy;
  {
    const std::lock_guard lock(mutex_);
    copy = pose_;
  }
  if (copy) {
    copy->time = time;
  }
  return copy;
}

}  // namespace incise
