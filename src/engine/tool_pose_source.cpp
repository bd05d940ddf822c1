#include "incise/engine/tool_pose_source.hpp"

#include <utility>

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

namespace {

bool same_place(const BladePose& a, const BladePose& b) {
  return a.tip == b.tip && a.base == b.base;
}

void keep_passed(std::vector<std::optional<BladePose>>& passed, std::optional<BladePose> pose) {
  if (passed.size() >= LiveToolPose::kMaxPassed) {
    passed.erase(passed.begin());
  }
  passed.push_back(std::move(pose));
}

}  // namespace

void LiveToolPose::set(const BladePose& pose) {
  const std::lock_guard lock(mutex_);
  if (!pose_) {
    keep_passed(passed_, pose);  // a stroke begins here
  }
  pose_ = pose;
}

void LiveToolPose::lift() {
  const std::lock_guard lock(mutex_);
  if (pose_) {
    if (!read_ || !same_place(*read_, *pose_)) {
      keep_passed(passed_, pose_);  // the stroke ends here, where the engine has not been
    }
    keep_passed(passed_, std::nullopt);
  }
  pose_.reset();
}

bool LiveToolPose::has_passed() {
  const std::lock_guard lock(mutex_);
  return !passed_.empty();
}

ToolMotion LiveToolPose::motion(int /*frame*/, double time) {
  ToolMotion motion;
  {
    const std::lock_guard lock(mutex_);
    motion.passed = std::exchange(passed_, {});
    motion.pose = pose_;
    read_ = pose_;
  }
  // A stroke that began at the newest pose: the pose itself says so.
  if (!motion.passed.empty() && motion.passed.back() && motion.pose &&
      same_place(*motion.passed.back(), *motion.pose)) {
    motion.passed.pop_back();
  }
  for (auto& pose : motion.passed) {
    if (pose) {
      pose->time = time;
    }
  }
  if (motion.pose) {
    motion.pose->time = time;
  }
  return motion;
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
