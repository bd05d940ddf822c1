#pragma once
// The haptic loop: its own thread at a fixed rate (1 kHz for a desktop device), never blocked
// by the physics. Each tick it takes the newest device pose, evaluates the contact model the
// physics last published, filters the force (limit, largest step) and hands it on.
//
// Thread rule: set_model() from the physics thread (once per frame), post_pose() from the
// network thread (each message), statistics() from any thread; the loop itself runs on the
// thread start() creates, which alone calls the force callback. Nothing is shared by lock
// with the physics for longer than a pointer copy: the model is an immutable snapshot
// swapped through a SharedSlot.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "incise/core/shared_slot.hpp"
#include "incise/haptics/contact_model.hpp"

namespace incise {

using SteadyTime = std::chrono::steady_clock::time_point;

/// A device pose as it arrived: the blade, the device's own time stamp (s; 0: none) and when
/// it was received (the start of the pose-to-force latency).
struct DevicePose {
  BladePose blade;                 ///< m, in the body's world frame
  double device_time = 0.0;        ///< s, the device's stamp (0: none)
  std::uint64_t device_stamp = 0;  ///< the message's raw time stamp, echoed with the force
  SteadyTime received{};           ///< when it arrived
  std::uint64_t sequence = 0;      ///< grows with every pose posted
};

/// Durations (s) recorded in 1-microsecond bins up to 100 ms (above: counted at the top) for
/// exact-enough percentiles without keeping every sample.
class DurationHistogram {
 public:
  DurationHistogram();
  /// Records one duration (s).
  void add(double seconds);
  /// Durations recorded.
  [[nodiscard]] std::uint64_t count() const { return count_; }
  /// The q-th quantile (q in [0, 1]) in s; 0 when empty.
  [[nodiscard]] double quantile(double q) const;
  /// The longest (s).
  [[nodiscard]] double max() const { return max_; }
  /// The mean (s); 0 when empty.
  [[nodiscard]] double mean() const { return count_ ? sum_ / static_cast<double>(count_) : 0.0; }

 private:
  std::vector<std::uint32_t> bins_;
  std::uint64_t count_ = 0;
  double sum_ = 0.0;
  double max_ = 0.0;
};

/// Ticks at a fixed rate against absolute deadlines (no drift), with the kernel's timer
/// slack set to nothing for the calling thread: a device loop's clock.
class PeriodicClock {
 public:
  explicit PeriodicClock(double rate);  ///< Hz
  /// Sleeps to the next deadline; returns the time it woke. A tick that comes a whole period
  /// late skips ahead (counted by overran()) instead of bursting to catch up.
  SteadyTime wait();
  /// Whether the last wait skipped a late tick.
  [[nodiscard]] bool overran() const { return overran_; }

 private:
  std::chrono::nanoseconds period_;
  SteadyTime deadline_;
  bool overran_ = false;
};

/// Asks for real-time (FIFO) scheduling of the calling thread; false when not permitted.
bool request_realtime_priority();

/// How the haptic loop kept time (the serve report's `haptics`).
struct HapticStatistics {
  bool realtime = false;        ///< the loop ran with real-time priority
  std::uint64_t ticks = 0;      ///< loop iterations
  std::uint64_t overruns = 0;   ///< ticks that started a whole period late (skipped ahead)
  double period_p50 = 0.0;      ///< s
  double period_p99 = 0.0;      ///< s
  double period_max = 0.0;      ///< s
  std::uint64_t latencies = 0;  ///< new poses answered by a force
  double latency_p50 = 0.0;     ///< s, pose received to its force handed on
  double latency_p99 = 0.0;     ///< s
  double latency_max = 0.0;     ///< s
  double largest_force = 0.0;   ///< N
  double largest_step = 0.0;    ///< N between consecutive samples
};

/// The device's force loop (1 kHz by default) on its own thread: each tick evaluates the
/// physics' latest contact model at the newest pose, filters the force and hands it on.
/// post_pose, release, set_model, latest_pose and statistics may be called from any thread.
class HapticLoop {
 public:
  /// Called on the loop's thread with each tick's filtered force (N) and the pose it answers
  /// (none before the first pose: no force is sent then).
  using ForceCallback = std::function<void(const Vec3& force, const DevicePose& pose)>;

  /// A loop at `spec`'s rate and limits; it starts with start().
  HapticLoop(const HapticSpec& spec, ForceCallback on_force);
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  /// Starts the loop's thread (real-time priority where permitted).
  void start();
  /// Stops and joins it.
  void stop();
  /// The device's newest pose (any thread).
  void post_pose(const DevicePose& pose);
  /// The device left: the force eases to zero and the velocity estimate starts afresh.
  void release();
  /// The physics' newest model (any thread; the physics thread once per frame).
  void set_model(std::shared_ptr<const ContactModel> model);
  /// The newest pose posted, if any.
  [[nodiscard]] std::optional<DevicePose> latest_pose() const;
  /// The loop's timing so far.
  [[nodiscard]] HapticStatistics statistics() const;

 private:
  void run();

  HapticSpec spec_;
  ForceCallback on_force_;
  SharedSlot<const ContactModel> model_;
  mutable std::mutex pose_mutex_;
  std::optional<DevicePose> pose_;
  std::uint64_t posted_ = 0;
  mutable std::mutex statistics_mutex_;
  DurationHistogram periods_;
  DurationHistogram latencies_;
  HapticStatistics counters_;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace incise
