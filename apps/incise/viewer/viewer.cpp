#include "viewer.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/render/gl_backend.hpp"
#include "incise/solve/linear_solvers.hpp"
#include "incise/view/frame_scene.hpp"
#include "window.hpp"

namespace incise::app {

namespace {

Viewer& viewer_of(GLFWwindow* window) {
  return *static_cast<Viewer*>(glfwGetWindowUserPointer(window));
}

constexpr std::size_t kTimingFrames = 240;
/// After input the panels are drawn for this long (hover states, tooltips, popups).
constexpr auto kSettle = std::chrono::milliseconds(500);
/// The longest the window sleeps without input or a physics frame.
constexpr double kIdleWakeSeconds = 0.25;

void push(std::deque<float>& series, double value) {
  series.push_back(static_cast<float>(value));
  if (series.size() > kTimingFrames) {
    series.pop_front();
  }
}

}  // namespace

struct Viewer::Graphics {
  GlBackend backend;
  Renderer renderer{backend};
};

Viewer::Viewer(ViewerOptions options) : options_(std::move(options)) {
  window_ = open_window(options_.width, options_.height, "incise", options_.exit_after >= 0 ? 0 : 1,
                        this);
  // Installed before ImGui's, which chain to them.
  glfwSetScrollCallback(
      window_, [](GLFWwindow* window, double, double y) { viewer_of(window).on_scroll(y); });
  glfwSetKeyCallback(window_, [](GLFWwindow* window, int key, int, int action, int) {
    viewer_of(window).on_input();
    if (action == GLFW_PRESS) {
      viewer_of(window).on_key(key);
    }
  });
  glfwSetCursorPosCallback(
      window_, [](GLFWwindow* window, double, double) { viewer_of(window).on_cursor_move(); });
  glfwSetMouseButtonCallback(
      window_, [](GLFWwindow* window, int, int, int) { viewer_of(window).on_input(); });
  glfwSetCharCallback(window_,
                      [](GLFWwindow* window, unsigned int) { viewer_of(window).on_input(); });
  glfwSetCursorEnterCallback(window_,
                             [](GLFWwindow* window, int) { viewer_of(window).on_input(); });
  glfwSetWindowFocusCallback(window_,
                             [](GLFWwindow* window, int) { viewer_of(window).on_input(); });
  glfwSetFramebufferSizeCallback(
      window_, [](GLFWwindow* window, int, int) { viewer_of(window).on_input(); });
  glfwSetWindowRefreshCallback(window_, [](GLFWwindow* window) { viewer_of(window).on_input(); });
  start_imgui(window_);
  graphics_ = std::make_unique<Graphics>();

  if (options_.replay) {
    replay_ = read_session(*options_.replay);
    scene_ = replay_->segments.back().scene();
  } else {
    scene_ = options_.scene_file ? load_scene(*options_.scene_file) : default_scene();
  }
  render_.mode = options_.mode;
  settings_.young_modulus = static_cast<float>(scene_.material.young_modulus);
  settings_.poisson_ratio = static_cast<float>(scene_.material.poisson_ratio);
  settings_.density = static_cast<float>(scene_.material.density);
  settings_.integrator = static_cast<int>(scene_.integrator.type);
  settings_.dt = static_cast<float>(scene_.integrator.dt);
  settings_.split = static_cast<int>(scene_.tool.split);
  settings_.preconditioner =
      static_cast<int>(scene_.integrator.backward_euler.solver.preconditioner);
  start_engine();
}

Viewer::~Viewer() {
  thread_.reset();  // the physics stops before its sinks and engine go
  engine_.reset();
  graphics_.reset();
  close_window(window_);
}

void Viewer::start_engine() {
  thread_.reset();  // stopped: pending actions are recorded into the old segment
  engine_.reset();  // its sinks go before they are replaced
  hand_ = nullptr;
  if (replay_) {
    engine_ = replay_engine(replay_->segments.back());
  } else {
    const SceneDescription scene = viewer_scene(scene_);
    engine_ = std::make_unique<Engine>(scene);
    auto tool = std::make_unique<HandOverTool>(
        scene.tool.poses.empty() ? nullptr : std::make_unique<ScriptedToolPath>(scene.tool.poses));
    hand_ = tool.get();
    engine_->set_tool_source(std::move(tool));
  }
  if (options_.record) {
    engine_->add_sink(recorder_.emplace(recording_));
  }
  if (options_.out) {
    const std::string name = scene_.file.empty() ? "default" : scene_.file.stem().string();
    series_ = std::make_unique<VtuSeriesSink>(*options_.out, name, 1 << 30);
    engine_->add_sink(*series_);
  }
  integrator_name_ = std::string(engine_->integrator().name());
  engine_->publish_snapshots(true);
  snapshot_ = engine_->snapshots().latest();
  seen_frame_ = snapshot_->frame;
  const Bounds body = frame_scene(snapshot_).bounds();
  body_radius_ = body.radius();
  if (!camera_fitted_) {
    render_.camera = scene_camera(engine_->scene(), body, aspect());
    camera_fitted_ = true;
  }
  depth_ = 0.3 * body_radius_;
  anchor_.reset();
  for (auto* series : {&timing_.cd, &timing_.gc, &timing_.rx, &timing_.rd}) {
    series->clear();
  }
  // Interactive: paced to the scene's frame time; scripted (--exit-after): as fast as it goes.
  // Each physics frame wakes the window (glfwPostEmptyEvent may be called from any thread).
  thread_ = std::make_unique<EngineThread>(*engine_, playing_, options_.exit_after,
                                           options_.exit_after < 0 || options_.paced,
                                           [] { glfwPostEmptyEvent(); });
  shown_finished_ = false;
  settle_until_ = Clock::now() + kSettle;
}

double Viewer::aspect() const {
  int width = 0;
  int height = 0;
  glfwGetFramebufferSize(window_, &width, &height);
  return height > 0 ? static_cast<double>(width) / height : 1.0;
}

void Viewer::action(const std::string& name, const std::string& value) {
  if (recorder_ && thread_) {
    // On the engine's thread, between frames: the action gets the frame it happened before.
    thread_->run_on_engine(
        [this, name, value](Engine& engine) { recorder_->action(engine.frame(), name, value); });
  }
}

void Viewer::on_key(int key) {
  keys_.push_back(key);
}

bool Viewer::take_snapshot() {
  snapshot_ = engine_->snapshots().latest();
  if (snapshot_->frame == seen_frame_) {
    return false;
  }
  const int previous = seen_frame_;
  seen_frame_ = snapshot_->frame;
  physics_frames_ += std::max(0, seen_frame_ - previous);
  push(timing_.cd, 1e3 * snapshot_->cd);
  push(timing_.gc, 1e3 * snapshot_->gc);
  push(timing_.rx, 1e3 * snapshot_->rx);
  push(timing_.rd, draw_ms_);
  if (replay_) {
    // The replayed session's view changes, at the frames they were made (or the first drawn
    // after them).
    for (const SessionAction& recorded : replay_->segments.back().actions) {
      if (recorded.frame <= previous || recorded.frame > seen_frame_) {
        continue;
      }
      if (recorded.name == "mode") {
        render_.mode = parse_render_mode(recorded.value).value_or(render_.mode);
      } else if (recorded.name == "highlight") {
        highlight_active_ = recorded.value == "on";
      }
    }
  }
  return true;
}

void Viewer::wait_for_events() {
  if (Clock::now() < settle_until_ || pending_screenshot_) {
    glfwPollEvents();
  } else {
    // Input, or the physics thread's empty event after each frame, ends the wait.
    glfwWaitEventsTimeout(kIdleWakeSeconds);
  }
}

bool Viewer::needs_drawing(bool new_snapshot, bool finished) {
  const auto now = Clock::now();
  const bool input = input_events_ != seen_input_events_ || !keys_.empty() || scroll_ != 0.0;
  // A cursor move changes the picture only while it turns the camera or moves over the
  // panels; one that steers a held scalpel shows in the physics' next snapshot.
  const bool over_panels = ImGui::GetIO().WantCaptureMouse;
  const bool cursor = cursor_moves_ != seen_cursor_moves_ && (dragging_camera_ || over_panels);
  seen_input_events_ = input_events_;
  seen_cursor_moves_ = cursor_moves_;
  if (input || (cursor && over_panels)) {
    settle_until_ = now + kSettle;
  }
  const bool finish_changed = finished != shown_finished_;
  shown_finished_ = finished;
  return new_snapshot || input || cursor || finish_changed || pending_screenshot_ ||
         now < settle_until_;
}

void Viewer::handle_mouse() {
  const ImGuiIO& io = ImGui::GetIO();
  double x = 0.0;
  double y = 0.0;
  glfwGetCursorPos(window_, &x, &y);
  int width = 1;
  int height = 1;
  glfwGetWindowSize(window_, &width, &height);
  const double nx = 2.0 * x / std::max(width, 1) - 1.0;
  const double ny = 1.0 - 2.0 * y / std::max(height, 1);
  const bool left = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
  const bool right = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
  const bool middle = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
  const Ray ray = cursor_ray(render_.camera, aspect(), nx, ny);
  const bool free = !io.WantCaptureMouse;

  if (free && left && !anchor_ && !dragging_camera_) {
    // A press on the body takes the scalpel; beside it, the camera.
    const FrameScene scene = frame_scene(snapshot_);
    const auto hit = hand_ != nullptr ? pick_surface(ray, scene.surface->triangles, scene.positions)
                                      : std::nullopt;
    if (hit) {
      anchor_ = hit->point;
      if (!hand_->taken()) {
        hand_->take();
        action("take");
      }
    } else {
      dragging_camera_ = true;
    }
  }
  if (free && (right || middle) && !anchor_) {
    dragging_camera_ = true;
  }
  if (scroll_ != 0.0) {
    if (anchor_) {
      depth_ *= std::pow(1.15, scroll_);  // scroll sets how deep the blade reaches
    } else if (free) {
      zoom(render_.camera, std::pow(0.9, scroll_));
    }
    scroll_ = 0.0;
  }
  if (anchor_ && hand_ != nullptr) {
    if (left) {
      hand_->live().set(scalpel_pose(render_.camera, ray, *anchor_, depth_, 0.6 * body_radius_));
    } else {
      hand_->live().lift();
      anchor_.reset();
    }
  }
  if (dragging_camera_) {
    const double dx = (x - last_x_) / std::max(height, 1);
    const double dy = (y - last_y_) / std::max(height, 1);
    const bool shift = glfwGetKey(window_, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS;
    if (middle || (right && shift)) {
      pan(render_.camera, -dx, dy);
    } else {
      orbit(render_.camera, -3.0 * dx, 3.0 * dy);
    }
    if (!left && !right && !middle) {
      dragging_camera_ = false;
    }
  }
  last_x_ = x;
  last_y_ = y;
}

void Viewer::draw_scene() {
  const auto start = Clock::now();
  int width = 0;
  int height = 0;
  glfwGetFramebufferSize(window_, &width, &height);
  if (width <= 0 || height <= 0) {
    return;  // minimised
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  render_.width = width;
  render_.height = height;
  const FrameScene scene = frame_scene(snapshot_, highlight_active_);
  graphics_->renderer.render(scene.input(), render_);
  glFinish();  // what the frame costs, not what the driver queued
  draw_ms_ = 1e3 * seconds_since(start);
}

void Viewer::save_screenshot(const std::filesystem::path& path) {
  write_png(path, read_window_picture(window_));
  message_ = "saved " + path.string();
  action("screenshot", path.string());
}

bool Viewer::preconditioner_applies() const {
  const auto integrator = static_cast<IntegratorKind>(settings_.integrator);
  return scene_.model_type == ModelKind::kCorotationalFem &&
         (integrator == IntegratorKind::kBackwardEuler || integrator == IntegratorKind::kStatic);
}

void Viewer::apply_settings() {
  nlohmann::json root = nlohmann::json::parse(scene_.source_text);
  root["material"] = {{"young_modulus", settings_.young_modulus},
                      {"poisson_ratio", settings_.poisson_ratio},
                      {"density", settings_.density}};
  if (!root.contains("integrator") || !root["integrator"].is_object()) {
    root["integrator"] = nlohmann::json::object();
  }
  root["integrator"]["type"] = name_of(static_cast<IntegratorKind>(settings_.integrator));
  root["integrator"]["dt"] = settings_.dt;
  if (preconditioner_applies()) {
    nlohmann::json& solver = root["integrator"]["solver"];
    if (!solver.is_object()) {
      solver = nlohmann::json::object();
    }
    solver["preconditioner"] = to_string(static_cast<Preconditioner>(settings_.preconditioner));
  }
  if (!root.contains("cutter") || !root["cutter"].is_object()) {
    root["cutter"] = {{"type", "subdivision"}};
  }
  root["cutter"]["split"] = name_of(static_cast<SplitMode>(settings_.split));
  if (root.contains("frame_dt") && root["frame_dt"].is_number() &&
      std::fmod(root["frame_dt"].get<double>(), settings_.dt) > 1e-12) {
    root.erase("frame_dt");  // a frame is then one step of the new dt
  }
  try {
    SceneDescription scene = parse_scene(root.dump(2), scene_.file);
    scene_ = std::move(scene);
    action("reset", "settings");
    start_engine();
    message_ = "settings applied";
  } catch (const Error& error) {
    message_ = error.what();
  }
}

int Viewer::run() {
  bool screenshot_saved = false;
  // Drawn frames (events, drawing, panels, swap) and physics frames over the run's wall time.
  double draw_seconds = 0.0;
  int drawn_frames = 0;
  const auto run_start = Clock::now();
  while (glfwWindowShouldClose(window_) == 0) {
    wait_for_events();
    const auto frame_start = std::chrono::steady_clock::now();
    // Asked before the snapshot is taken: once finished, the snapshot is the last frame.
    const bool finished = thread_->finished();
    const bool new_snapshot = take_snapshot();
    if (!needs_drawing(new_snapshot, finished)) {
      handle_mouse();  // a held scalpel follows the cursor between drawn frames
      continue;
    }
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    const bool keyboard_free = !ImGui::GetIO().WantCaptureKeyboard;
    while (!keys_.empty()) {
      const int key = keys_.front();
      keys_.pop_front();
      if (!keyboard_free) {
        continue;
      }
      const auto set_mode = [this](RenderMode mode) {
        render_.mode = mode;
        action("mode", std::string(name_of(mode)));
      };
      switch (key) {
        case GLFW_KEY_F:
          set_mode(RenderMode::kFaces);
          break;
        case GLFW_KEY_G:
          set_mode(RenderMode::kWire);
          break;
        case GLFW_KEY_C:
          set_mode(RenderMode::kCut);
          break;
        case GLFW_KEY_H:
          highlight_active_ = !highlight_active_;
          action("highlight", highlight_active_ ? "on" : "off");
          break;
        case GLFW_KEY_SPACE:
          thread_->set_playing(!thread_->playing());
          action(thread_->playing() ? "play" : "pause");
          break;
        case GLFW_KEY_N:
          action("step");
          thread_->step_once();
          break;
        case GLFW_KEY_R:
          action("reset");
          start_engine();
          break;
        case GLFW_KEY_P:
          pending_screenshot_ = "incise_screenshot.png";
          break;
        case GLFW_KEY_ESCAPE:
          glfwSetWindowShouldClose(window_, GLFW_TRUE);
          break;
        default:
          break;
      }
    }
    handle_mouse();
    draw_scene();
    draw_seconds += 1e-3 * draw_ms_;
    ++drawn_frames;
    // The physics thread stops at exit_after, or earlier if the simulation diverged.
    const bool done = options_.exit_after >= 0 && finished;
    if (finished && options_.exit_after < 0 && message_.empty()) {
      message_ = "the simulation diverged (the reason is printed at exit); reset with R";
    }
    if (pending_screenshot_) {
      save_screenshot(*pending_screenshot_);
      pending_screenshot_.reset();
    }
    if (done && options_.screenshot) {
      save_screenshot(*options_.screenshot);
      screenshot_saved = true;
    }
    draw_panels();
    ImGui::Render();
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    glfwSwapBuffers(window_);
    if (done) {
      break;
    }
    if (options_.exit_after < 0) {
      // At most 60 drawn frames/s: without vsync (Xvfb, some drivers) drawing would take the
      // cores the physics needs.
      std::this_thread::sleep_until(frame_start + std::chrono::microseconds(16'667));
    }
  }
  const double wall = seconds_since(run_start);
  const double physics_rate = thread_->frames_per_second();
  thread_->stop();  // the engine is this thread's again
  if (options_.screenshot && !screenshot_saved) {
    snapshot_ = engine_->snapshots().latest();
    draw_scene();
    save_screenshot(*options_.screenshot);
  }
  engine_->finish();
  if (options_.record) {
    write_session(*options_.record, recording_);
  }
  std::cerr << "incise view: " << engine_->frame() << " frames";
  if (drawn_frames > 0 && wall > 0.0) {
    std::cerr << "; drawn " << drawn_frames / wall << " frames/s (3-D drawing "
              << 1e3 * draw_seconds / drawn_frames << " ms), physics " << physics_frames_ / wall
              << " frames/s (" << physics_rate << " frames/s of stepping time)";
  }
  if (options_.record) {
    std::cerr << ", session recorded to " << options_.record->string();
  }
  std::cerr << "\n";
  if (engine_->diverged()) {
    std::cerr << "error: " << engine_->divergence() << "\n";
    return 3;
  }
  return 0;
}

}  // namespace incise::app
