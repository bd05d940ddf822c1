#pragma once
// The planning viewer's worker: a PlanSession on its own thread. It prepares the plan, then
// runs requests one at a time (a segment nudged, an osteotomy plane added, the plan saved),
// predicting the soft tissue after each change it accepts, warm-started after a nudge, and
// after each prediction, not busy, factorising where it ended for the next nudge; the window
// reads the latest published state.
// Only this thread touches the session; the window's thread calls request() and state().
// Requests run in order, so the same requests give the same predictions, bit for bit.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "incise/planning/plan.hpp"
#include "incise/planning/plan_session.hpp"

namespace incise::app {

/// A segment's pose as the viewer builds it: a translation (mm) and a rotation about the
/// segment's centre (its vertices' mean, m), composed nudge by nudge.
struct SegmentPose {
  Vec3 translation_mm = Vec3::Zero();
  Mat3 rotation = Mat3::Identity();
};

/// What the window shows (copied under the worker's lock).
struct PlanState {
  std::uint64_t revision = 0;  ///< changes whenever anything below does
  bool ready = false;          ///< prepared (and predicted once)
  bool busy = true;            ///< preparing or running a request
  std::string status;          ///< what it is doing or last did
  std::string error;           ///< preparing failed: the message
  std::vector<Triangle> skin_triangles;
  std::vector<Vec3> skin_before;  ///< m
  std::vector<Vec3> skin_after;   ///< m, the last prediction
  double largest_displacement_mm = 0.0;
  /// The bone as a triangle soup (three corners per triangle, moved), m, and each triangle's
  /// segment.
  std::vector<Vec3> bone_corners;
  std::vector<int> bone_segment;
  std::vector<double> segment_volumes_mm3;
  std::vector<SegmentPose> poses;
  /// m, per segment: where its pose's rotation turns it about, before its translation.
  std::vector<Vec3> segment_centres;
  int predictions = 0;
  int osteotomies = 0;  ///< the plan's planes, its own and those added by hand
};

/// A request: nudge a segment (translation in mm, rotation in degrees about the segment's
/// centre along x, y, z, applied after its current pose), cut the bone by one more osteotomy
/// plane (through point_mm, across normal; the plan is prepared again with it, the moves made
/// so far kept with the part that holds each moved segment's largest triangle), or save the
/// plan with its planes and moves.
struct PlanRequest {
  enum class Kind { kNudge, kCut, kSave } kind = Kind::kNudge;
  int segment = 0;
  Vec3 translate_mm = Vec3::Zero();
  Vec3 rotate_deg = Vec3::Zero();
  Vec3 point_mm = Vec3::Zero();  ///< kCut
  Vec3 normal = Vec3::UnitZ();   ///< kCut
  std::filesystem::path path;    ///< kSave
};

class PlanWorker {
 public:
  /// Starts preparing `plan` (whose JSON text is `plan_text`, for saving); `on_change` runs on
  /// this thread after each published change (the window wakes up to draw it).
  PlanWorker(planning::PlanDescription plan, std::string plan_text,
             std::function<void()> on_change);
  ~PlanWorker();
  PlanWorker(const PlanWorker&) = delete;
  PlanWorker& operator=(const PlanWorker&) = delete;

  void request(PlanRequest request);
  [[nodiscard]] PlanState state() const;
  /// Whether every request so far has run (and preparing is over).
  [[nodiscard]] bool idle() const;

 private:
  void loop();
  void publish(const std::function<void(PlanState&)>& change);
  /// Prepares `plan` into a new session (the old one stays if it fails) and publishes it.
  void prepare(const planning::PlanDescription& plan);
  void nudge(const PlanRequest& request);
  void cut(const PlanRequest& request);
  void save(const std::filesystem::path& path);
  void predict();
  /// Publishes that the request is done (busy only while more wait), then factorises for the
  /// next nudge if a prediction was made.
  void finish_request();

  planning::PlanDescription plan_;
  std::string plan_text_;
  std::function<void()> on_change_;
  std::unique_ptr<planning::PlanSession> session_;  ///< this thread's
  std::vector<SegmentPose> poses_;                  ///< this thread's
  std::vector<Vec3> centres_;                       ///< m, per segment
  bool prepare_next_ = false;  ///< this thread's: a prediction not yet prepared from
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<PlanRequest> requests_;
  bool stopping_ = false;
  bool running_ = true;  ///< preparing or running a request
  PlanState state_;
  std::thread thread_;
};

}  // namespace incise::app
