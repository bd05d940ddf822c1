#include "incise/haptics/haptic_loop.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cmath>

#include "incise/core/error.hpp"

namespace incise {
namespace {

constexpr double kBinWidth = 1e-6;      // s
constexpr std::size_t kBins = 100'000;  // up to 100 ms

double seconds_between(SteadyTime from, SteadyTime to) {
  return std::chrono::duration<double>(to - from).count();
}

}  // namespace

DurationHistogram::DurationHistogram() : bins_(kBins + 1, 0) {}

void DurationHistogram::add(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) {
    seconds = 0.0;
  }
  const auto bin = static_cast<std::size_t>(std::min(seconds / kBinWidth, double(kBins)));
  ++bins_[bin];
  ++count_;
  sum_ += seconds;
  max_ = std::max(max_, seconds);
}

double DurationHistogram::quantile(double q) const {
  if (count_ == 0) {
    return 0.0;
  }
  const auto rank =
      static_cast<std::uint64_t>(std::ceil(std::clamp(q, 0.0, 1.0) * static_cast<double>(count_)));
  std::uint64_t seen = 0;
  for (std::size_t bin = 0; bin < bins_.size(); ++bin) {
    seen += bins_[bin];
    if (seen >= std::max<std::uint64_t>(rank, 1)) {
      return std::min((static_cast<double>(bin) + 0.5) * kBinWidth, max_);
    }
  }
  return max_;
}

HapticLoop::HapticLoop(const HapticSpec& spec, ForceCallback on_force)
    : spec_(spec), on_force_(std::move(on_force)) {
  INCISE_ASSERT(spec.rate > 0.0, "the haptic rate must be positive");
}

HapticLoop::~HapticLoop() {
  stop();
}

void HapticLoop::start() {
  if (running_.exchange(true)) {
    return;
  }
  thread_ = std::thread([this] { run(); });
}

void HapticLoop::stop() {
  running_ = false;
  if (thread_.joinable()) {
    thread_.join();
  }
}

void HapticLoop::post_pose(const DevicePose& pose) {
  const std::lock_guard lock(pose_mutex_);
  pose_ = pose;
  pose_->sequence = ++posted_;
}

void HapticLoop::release() {
  const std::lock_guard lock(pose_mutex_);
  pose_.reset();
}

void HapticLoop::set_model(std::shared_ptr<const ContactModel> model) {
  model_.store(std::move(model));
}

std::optional<DevicePose> HapticLoop::latest_pose() const {
  const std::lock_guard lock(pose_mutex_);
  return pose_;
}

HapticStatistics HapticLoop::statistics() const {
  const std::lock_guard lock(statistics_mutex_);
  HapticStatistics result = counters_;
  result.period_p50 = periods_.quantile(0.5);
  result.period_p99 = periods_.quantile(0.99);
  result.period_max = periods_.max();
  result.latencies = latencies_.count();
  result.latency_p50 = latencies_.quantile(0.5);
  result.latency_p99 = latencies_.quantile(0.99);
  result.latency_max = latencies_.max();
  return result;
}

PeriodicClock::PeriodicClock(double rate)
    : period_(static_cast<long long>(1e9 / rate)),
      deadline_(std::chrono::steady_clock::now() + period_) {
  INCISE_ASSERT(rate > 0.0, "a clock's rate must be positive");
  // The kernel's default timer slack (50 us) would be 5 % of a 1 ms period: ask for none.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
}

SteadyTime PeriodicClock::wait() {
  // Sleep to a little before the deadline, then spin the rest: a wake-up from sleep comes
  // tens of microseconds late on a busy machine, a spin of kSpin costs 5 % of one core.
  constexpr auto kSpin = std::chrono::microseconds(50);
  const auto since_epoch = (deadline_ - kSpin).time_since_epoch();
  timespec wake{};
  const auto whole = std::chrono::duration_cast<std::chrono::seconds>(since_epoch);
  wake.tv_sec = static_cast<time_t>(whole.count());
  wake.tv_nsec = static_cast<long>((since_epoch - whole).count());
  // steady_clock is CLOCK_MONOTONIC on Linux: sleep to the absolute time.
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
  }
  SteadyTime now = std::chrono::steady_clock::now();
  while (now < deadline_) {
    now = std::chrono::steady_clock::now();
  }
  deadline_ += period_;
  overran_ = now > deadline_;
  if (overran_) {
    deadline_ = now + period_;
  }
  return now;
}

bool request_realtime_priority() {
  // A device loop must not wait behind the physics for a core: real-time FIFO scheduling
  // when the process may have it (root, or CAP_SYS_NICE / an rtprio limit), else as is.
  sched_param parameters{};
  parameters.sched_priority = 20;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &parameters) == 0;
}

void HapticLoop::run() {
  const bool realtime = request_realtime_priority();
  {
    const std::lock_guard lock(statistics_mutex_);
    counters_.realtime = realtime;
  }
  PeriodicClock clock(spec_.rate);
  ForceFilter filter(spec_.force_limit, spec_.max_force_step);
  VelocityEstimator velocity;
  std::uint64_t last_sequence = 0;
  std::optional<SteadyTime> previous_tick;
  while (running_.load(std::memory_order_relaxed)) {
    const SteadyTime tick = clock.wait();
    const bool overrun = clock.overran();

    const std::optional<DevicePose> pose = latest_pose();
    const std::shared_ptr<const ContactModel> model = model_.load();
    Vec3 force = Vec3::Zero();
    bool fresh = false;
    if (pose) {
      fresh = pose->sequence != last_sequence;
      if (fresh) {
        const double time = pose->device_time > 0.0 ? pose->device_time
                                                    : seconds_between(SteadyTime{}, pose->received);
        velocity.add(time, pose->blade.tip);
        last_sequence = pose->sequence;
      }
      if (model) {
        force = evaluate_force(*model, pose->blade, velocity.velocity()).total();
      }
    } else {
      velocity.reset();
    }
    const Vec3 previous = filter.last();
    const Vec3 sent = filter.apply(force);
    if (pose && on_force_) {
      on_force_(sent, *pose);
    }
    const SteadyTime done = std::chrono::steady_clock::now();

    const std::lock_guard lock(statistics_mutex_);
    ++counters_.ticks;
    counters_.overruns += overrun ? 1 : 0;
    if (previous_tick) {
      periods_.add(seconds_between(*previous_tick, tick));
    }
    previous_tick = tick;
    if (pose && fresh) {
      latencies_.add(seconds_between(pose->received, done));
    }
    counters_.largest_force = std::max(counters_.largest_force, sent.norm());
    counters_.largest_step = std::max(counters_.largest_step, (sent - previous).norm());
  }
}

}  // namespace incise
