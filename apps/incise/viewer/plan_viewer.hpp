#pragma once
// `incise plan PLAN.json --view`: the planning scene in a window (the seed's interactive
// planning). The skin is drawn coloured by its predicted displacement (a colour bar in mm), or
// the bone with the selected segment in red; a segment is picked by clicking it (bone view) or
// from the list, and nudged by keys or buttons (mm and degrees); a nudge into another segment
// stops at contact. The prediction runs on the worker thread (PlanWorker), warm-started from
// the last, and the panel says "predicting..." until it is drawn. Save writes the plan with the
// moves made, which `incise plan` then runs. A session records its nudges and saves, and a
// recording replays to the same prediction, bit for bit.
//
// Osteotomy planes by hand: O (or the panel's button) shows a plane through the bone point
// under the cursor, across the screen's vertical; the arrows tilt it (degrees); a click or
// Enter cuts the bone there (the plan is prepared again with the plane: the worker's kCut), O
// or Esc puts it away.
//
// Mouse (bone view): drag the selected segment to move it, Shift+drag to turn it about its
// centre (about the axis towards the camera); click another to select it. Each prediction
// writes a line to the console.
// Keys: Tab / Shift+Tab select the next / previous segment; arrows move it along x and y,
// Page Up / Down along z (mm); with Shift they rotate it about those axes (degrees); B shows the
// bone or the skin; 1, 2, 3 look from the front, the side, above; O places a plane; S saves;
// P takes a picture; Esc closes.

#include <array>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "incise/render/renderer.hpp"
#include "incise/view/mouse_scalpel.hpp"
#include "plan_worker.hpp"

struct GLFWwindow;

namespace incise::app {

struct PlanViewerOptions {
  std::filesystem::path plan;
  std::optional<std::filesystem::path> record;      ///< the session's nudges and saves (JSON)
  std::optional<std::filesystem::path> replay;      ///< play a recording, then close
  std::optional<std::filesystem::path> screenshot;  ///< saved at exit
  /// Where Save writes the plan with its moves (default: PLAN_moved.json beside the plan).
  std::optional<std::filesystem::path> save;
  int width = 1280;
  int height = 800;
};

class PlanViewer {
 public:
  explicit PlanViewer(PlanViewerOptions options);
  ~PlanViewer();
  PlanViewer(const PlanViewer&) = delete;
  PlanViewer& operator=(const PlanViewer&) = delete;
  /// Runs until the window closes (or a replay has played); returns the exit code.
  int run();

  // From GLFW callbacks, on the window's thread.
  void on_key(int key, int mods) { keys_.push_back({key, mods}); }
  void on_scroll(double amount) { scroll_ += amount; }
  /// A press is kept until the next frame has seen it: a click whose press and release come
  /// in one batch of events (a slow frame) is still a click.
  void on_mouse_button(int button, int action);

 private:
  void handle_keys();
  void handle_mouse();
  void draw_scene();
  /// m: where the selected segment turns about (its centre, moved).
  [[nodiscard]] Vec3 selected_centre() const;
  /// The bone triangle under the cursor's ray (bone view), if any.
  std::optional<SurfaceHit> pick_bone(const Ray& ray);
  void draw_panel();
  void nudge(const Vec3& translate_mm, const Vec3& rotate_deg);
  void save();
  void start_placing_plane();
  /// Tilts the plane being placed by `degrees` about `axis` (a unit vector).
  void tilt_plane(const Vec3& axis, double degrees);
  void cut_at(const Vec3& point, const Vec3& normal);
  /// The plane being placed as a disc of triangle corners (three per triangle) over the bone.
  [[nodiscard]] std::vector<Vec3> plane_disc() const;
  void look_from(const Vec3& towards_camera);
  void save_screenshot(const std::filesystem::path& path);
  [[nodiscard]] double aspect() const;

  PlanViewerOptions options_;
  GLFWwindow* window_ = nullptr;
  struct Graphics;
  std::unique_ptr<Graphics> graphics_;
  std::unique_ptr<PlanWorker> worker_;
  PlanState state_;
  std::uint64_t drawn_revision_ = ~std::uint64_t{0};
  std::uint64_t surface_revision_ = 0;
  int drawn_selection_ = -1;
  bool drawn_bone_view_ = false;
  bool drawn_placing_plane_ = false;  ///< the last frame drew a plane being placed

  std::vector<Triangle> soup_;   ///< the bone view's triangles (three corners each)
  std::vector<double> scalars_;  ///< per drawn vertex
  std::vector<std::uint8_t> exterior_;
  std::vector<Vec3> dragged_;  ///< m: the bone's corners with a dragged segment moved
  std::vector<Vec3> shown_;    ///< m: what the bone view draws (the bone, a plane being placed)
  bool placing_plane_ = false;
  Vec3 plane_normal_ = Vec3::UnitZ();
  std::optional<Vec3> plane_point_;  ///< m: the bone point under the cursor
  RenderOptions render_;
  bool camera_fitted_ = false;
  bool bone_view_ = false;
  int selected_ = 0;
  float step_mm_ = 1.0F;
  float step_deg_ = 1.0F;
  std::vector<PlanRequest> recorded_;  ///< the session's requests, in order

  // Mouse: in the bone view a press on the selected segment drags it (on the plane facing the
  // camera through where it was pressed; released, the drag is a nudge), with Shift turns it
  // about its centre (about the axis towards the camera), a click on another picks it;
  // elsewhere a drag turns the camera.
  std::optional<Vec3> drag_anchor_;  ///< m, where the segment was pressed
  Vec3 drag_offset_ = Vec3::Zero();  ///< m, how far it has been dragged
  bool drag_turns_ = false;          ///< the drag turns the segment (Shift was held)
  Ray drag_from_;                    ///< the cursor's ray where the drag started
  double drag_angle_ = 0.0;          ///< rad, how far it has been turned
  bool dragging_ = false;
  bool moved_while_pressed_ = false;
  double last_x_ = 0.0;
  double last_y_ = 0.0;
  double scroll_ = 0.0;
  std::array<bool, 3> pressed_{};  ///< left, right, middle pressed since the last frame
  struct Key {
    int key;
    int mods;
  };
  std::deque<Key> keys_;
};

}  // namespace incise::app
