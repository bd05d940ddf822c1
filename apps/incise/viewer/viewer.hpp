#pragma once
// `incise view`: a GLFW window with the body drawn by the OpenGL renderer, Dear ImGui panels
// (play, pause, step, reset; settings; mesh statistics; per-stage timing plot) and the mouse
// scalpel. The physics steps on its own thread (EngineThread), paced to the scene's frame time;
// the window draws the latest published snapshot, so a frame costs the larger of physics and
// drawing, not their sum. It draws only when there is something new (a physics frame wakes it
// through glfwPostEmptyEvent; input; the panels settling after input) and waits for events
// otherwise: drawing the same picture again took a core from the physics. A recording holds the
// pose each physics frame took, so it replays exactly whatever the frame rates were.

#include <array>
#include <chrono>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "engine_thread.hpp"
#include "incise/engine/engine.hpp"
#include "incise/render/renderer.hpp"
#include "incise/view/mouse_scalpel.hpp"
#include "incise/view/session_recording.hpp"

struct GLFWwindow;

namespace incise::app {

struct ViewerOptions {
  std::optional<std::filesystem::path> scene_file;  ///< none: the default scene
  std::optional<std::filesystem::path> replay;
  std::optional<std::filesystem::path> record;
  std::optional<std::filesystem::path> screenshot;  ///< saved at exit
  std::optional<std::filesystem::path> out;         ///< the first and last frame as a .vtu series
  int exit_after = -1;                              ///< frames to play, then exit
  /// With exit_after: the physics paced to the scene's frame time, as when a user watches
  /// (else it runs as fast as it goes); the window still draws without waiting for vsync.
  bool paced = false;
  int width = 1280;
  int height = 800;
  RenderMode mode = RenderMode::kFaces;
};

class Viewer {
 public:
  explicit Viewer(ViewerOptions options);
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;
  /// Runs until the window closes or exit_after frames have played; returns the exit code.
  int run();

  // Called from GLFW callbacks (on the window's thread, inside glfwPollEvents and
  // glfwWaitEvents*).
  void on_scroll(double amount) {
    scroll_ += amount;
    ++input_events_;
  }
  void on_key(int key);
  /// Any input but a cursor move: buttons, characters, resizes, focus.
  void on_input() { ++input_events_; }
  void on_cursor_move() { ++cursor_moves_; }

 private:
  struct Timing {
    std::deque<float> cd, gc, rx, rd;  ///< ms, the last frames
  };
  void start_engine();  ///< (re)builds the engine from scene_ (or the replay) and its thread
  /// The latest published frame, its timings and replayed actions; true if it is new.
  bool take_snapshot();
  /// Waits for input or a physics frame, unless the panels still need frames after input.
  void wait_for_events();
  /// Whether this pass has something new to show (else the window is not drawn again: on
  /// llvmpipe a drawn frame of a large body costs most of a core that the physics needs).
  [[nodiscard]] bool needs_drawing(bool new_snapshot, bool finished);
  void handle_mouse();
  void draw_scene();
  void draw_panels();
  void save_screenshot(const std::filesystem::path& path);
  void action(const std::string& name, const std::string& value = {});
  void apply_settings();
  /// Whether the settings' preconditioner is used: an FEM body with an implicit integrator
  /// (backward Euler or static), the ones that solve with the assembled matrix.
  [[nodiscard]] bool preconditioner_applies() const;
  [[nodiscard]] double aspect() const;

  ViewerOptions options_;
  GLFWwindow* window_ = nullptr;
  struct Graphics;
  std::unique_ptr<Graphics> graphics_;

  SceneDescription scene_;
  std::optional<SessionRecording> replay_;
  std::unique_ptr<Engine> engine_;
  std::unique_ptr<EngineThread> thread_;  ///< declared after engine_: stopped before it goes
  std::shared_ptr<const Snapshot> snapshot_;
  int seen_frame_ = -1;
  int physics_frames_ = 0;  ///< frames the physics stepped while the window was open
  std::string integrator_name_;
  HandOverTool* hand_ = nullptr;  ///< owned by engine_; null while replaying
  std::unique_ptr<FrameSink> series_;
  SessionRecording recording_;
  std::optional<SessionRecorder> recorder_;

  RenderOptions render_;
  bool camera_fitted_ = false;
  bool highlight_active_ = false;
  bool playing_ = true;  ///< whether a new engine starts playing
  std::string message_;  ///< the last error or note shown in the panel

  // Mouse: the scalpel while the left button is held on the body, else the camera.
  std::optional<Vec3> anchor_;
  double depth_ = 0.0;        ///< m
  double body_radius_ = 0.0;  ///< m, at the start: sizes the blade and its depth range
  bool dragging_camera_ = false;
  double last_x_ = 0.0;
  double last_y_ = 0.0;
  double scroll_ = 0.0;
  std::deque<int> keys_;
  // Redrawing on demand: what the window has seen of the input, and until when the panels
  // keep being drawn after input (hover, tooltips and popups need a few frames).
  int input_events_ = 0;
  int cursor_moves_ = 0;
  int seen_input_events_ = 0;
  int seen_cursor_moves_ = 0;
  std::chrono::steady_clock::time_point settle_until_{};
  bool shown_finished_ = false;
  std::optional<std::filesystem::path> pending_screenshot_;

  // Settings being edited (applied with a reset).
  struct Settings {
    float young_modulus = 0;  ///< Pa
    float poisson_ratio = 0;
    float density = 0;  ///< kg/m^3
    int integrator = 0;
    float dt = 0;  ///< s
    int split = 0;
    int preconditioner = 0;  ///< a Preconditioner (FEM bodies with an implicit integrator)
  } settings_;
  Timing timing_;
  double draw_ms_ = 0.0;
};

}  // namespace incise::app
