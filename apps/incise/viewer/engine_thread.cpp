#include "engine_thread.hpp"

#include <chrono>
#include <utility>

#include "incise/core/timing.hpp"

namespace incise::app {

EngineThread::EngineThread(Engine& engine, bool playing, int stop_at, bool paced,
                           std::function<void()> on_frame)
    : engine_(&engine),
      stop_at_(stop_at),
      paced_(paced),
      on_frame_(std::move(on_frame)),
      playing_(playing),
      finished_(engine.diverged() || (stop_at >= 0 && engine.frame() >= stop_at)) {
  thread_ = std::thread([this] { loop(); });
}

EngineThread::~EngineThread() {
  stop();
}

void EngineThread::set_playing(bool playing) {
  {
    const std::lock_guard lock(mutex_);
    playing_ = playing;
  }
  wake_.notify_one();
}

bool EngineThread::playing() const {
  const std::lock_guard lock(mutex_);
  return playing_;
}

void EngineThread::step_once() {
  {
    const std::lock_guard lock(mutex_);
    ++steps_;
  }
  wake_.notify_one();
}

void EngineThread::run_on_engine(std::function<void(Engine&)> command) {
  {
    const std::lock_guard lock(mutex_);
    commands_.push_back(std::move(command));
  }
  wake_.notify_one();
}

void EngineThread::stop() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) {
    thread_.join();
  }
  // Commands sent after the last frame still run, on this thread now that the engine is ours.
  for (auto& command : commands_) {
    command(*engine_);
  }
  commands_.clear();
}

bool EngineThread::finished() const {
  const std::lock_guard lock(mutex_);
  return finished_;
}

double EngineThread::frames_per_second() const {
  const std::lock_guard lock(mutex_);
  return stepping_seconds_ > 0.0 ? stepped_ / stepping_seconds_ : 0.0;
}

void EngineThread::loop() {
  using Wall = std::chrono::steady_clock;
  const double frame_dt = engine_->scene().frame_dt;
  auto next = Wall::now();
  std::unique_lock lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] {
      const bool more = !finished_ && (playing_ || steps_ > 0);
      return stopping_ || !commands_.empty() || more;
    });
    std::vector<std::function<void(Engine&)>> commands;
    commands.swap(commands_);
    lock.unlock();
    for (auto& command : commands) {
      command(*engine_);
    }
    lock.lock();
    if (stopping_) {
      return;
    }
    if (finished_ || !(playing_ || steps_ > 0) || !commands_.empty()) {
      next = Wall::now();  // paused: pacing starts again from the next frame
      continue;
    }
    steps_ = std::max(0, steps_ - 1);
    lock.unlock();
    const auto start = Clock::now();
    const bool ok = engine_->step();
    const double seconds = seconds_since(start);
    lock.lock();
    ++stepped_;
    stepping_seconds_ += seconds;
    if (!ok || (stop_at_ >= 0 && engine_->frame() >= stop_at_)) {
      finished_ = true;
      playing_ = false;
    }
    lock.unlock();
    if (on_frame_) {
      // The snapshot is published and finished() says whether it was the last: the window
      // may draw it now, while this thread paces.
      on_frame_();
    }
    if (paced_) {
      next += std::chrono::duration_cast<Wall::duration>(std::chrono::duration<double>(frame_dt));
      if (next > Wall::now()) {
        std::this_thread::sleep_until(next);
      } else {
        next = Wall::now();  // behind: do not try to catch up
      }
    }
    lock.lock();
  }
}

}  // namespace incise::app
