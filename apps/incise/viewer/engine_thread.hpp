#pragma once
// The viewer's physics thread: steps an engine while playing, paced to the scene's frame time
// (or as fast as it can), and runs commands on it between frames. The window's thread never
// touches the engine while this runs: it draws the engine's published snapshots (the engine's
// thread rule), sets the live tool pose, and sends commands.

#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "incise/engine/engine.hpp"

namespace incise::app {

class EngineThread {
 public:
  /// Starts stepping `engine` (paused unless `playing`); stops by itself after frame
  /// `stop_at` (-1: never). `paced`: no faster than one frame per frame_dt of wall time.
  /// `on_frame` runs on this thread after every frame (and when it finishes): the window uses
  /// it to wake up and draw the new snapshot; it must be safe to call from another thread.
  EngineThread(Engine& engine, bool playing, int stop_at, bool paced,
               std::function<void()> on_frame = {});
  ~EngineThread();
  EngineThread(const EngineThread&) = delete;
  EngineThread& operator=(const EngineThread&) = delete;

  void set_playing(bool playing);
  [[nodiscard]] bool playing() const;
  void step_once();
  /// Runs `command` on the engine's thread before its next frame.
  void run_on_engine(std::function<void(Engine&)> command);
  /// Stops and joins: afterwards the engine is the caller's again.
  void stop();
  /// Whether it stepped to `stop_at` or the engine diverged.
  [[nodiscard]] bool finished() const;
  /// Physics frames per second of the time spent in Engine::step.
  [[nodiscard]] double frames_per_second() const;

 private:
  void loop();
  Engine* engine_;
  int stop_at_;
  bool paced_;
  std::function<void()> on_frame_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool playing_;
  int steps_ = 0;
  bool stopping_ = false;
  bool finished_ = false;
  int stepped_ = 0;
  double stepping_seconds_ = 0.0;
  std::vector<std::function<void(Engine&)>> commands_;
  std::thread thread_;
};

}  // namespace incise::app
