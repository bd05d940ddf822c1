#include "plan_viewer.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <fmt/format.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <thread>

#include "incise/core/atomic_file.hpp"
#include "incise/core/error.hpp"
#include "incise/render/colour_map.hpp"
#include "incise/render/gl_backend.hpp"
#include "incise/render/image.hpp"
#include "incise/view/mouse_scalpel.hpp"
#include "window.hpp"

namespace incise::app {

namespace {

PlanViewer& viewer_of(GLFWwindow* window) {
  return *static_cast<PlanViewer*>(glfwGetWindowUserPointer(window));
}

std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw InputError(path.string(), 0, "cannot read the file");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

nlohmann::json to_json(const PlanRequest& request) {
  if (request.kind == PlanRequest::Kind::kSave) {
    return {{"save", request.path.string()}};
  }
  if (request.kind == PlanRequest::Kind::kCut) {
    const Vec3& p = request.point_mm;
    const Vec3& n = request.normal;
    return {{"cut", {{"point_mm", {p.x(), p.y(), p.z()}}, {"normal", {n.x(), n.y(), n.z()}}}}};
  }
  const Vec3& t = request.translate_mm;
  const Vec3& r = request.rotate_deg;
  return {{"nudge",
           {{"segment", request.segment},
            {"translate_mm", {t.x(), t.y(), t.z()}},
            {"rotate_deg", {r.x(), r.y(), r.z()}}}}};
}

/// A recording's requests; errors name the file and the entry.
std::vector<PlanRequest> read_recording(const std::filesystem::path& path) {
  std::vector<PlanRequest> requests;
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(slurp(path));
    for (std::size_t i = 0; i < root.at("requests").size(); ++i) {
      const nlohmann::json& item = root["requests"][i];
      PlanRequest request;
      const auto vec = [&](const nlohmann::json& object, const char* kind, const char* key) {
        const auto v = object.at(key).get<std::vector<double>>();
        if (v.size() != 3) {
          throw InputError(path.string(), 0,
                           fmt::format("requests[{}].{}.{}: three numbers", i, kind, key));
        }
        return Vec3(v[0], v[1], v[2]);
      };
      if (item.contains("save")) {
        request.kind = PlanRequest::Kind::kSave;
        request.path = item["save"].get<std::string>();
      } else if (item.contains("cut")) {
        request.kind = PlanRequest::Kind::kCut;
        request.point_mm = vec(item["cut"], "cut", "point_mm");
        request.normal = vec(item["cut"], "cut", "normal");
      } else {
        const nlohmann::json& nudge = item.at("nudge");
        request.segment = nudge.at("segment").get<int>();
        request.translate_mm = vec(nudge, "nudge", "translate_mm");
        request.rotate_deg = vec(nudge, "nudge", "rotate_deg");
      }
      requests.push_back(request);
    }
  } catch (const nlohmann::json::exception& error) {
    throw InputError(path.string(), 0,
                     std::string("not a planning recording ({\"plan\": ..., \"requests\": "
                                 "[...]}): ") +
                         error.what());
  }
  return requests;
}

}  // namespace

struct PlanViewer::Graphics {
  GlBackend backend;
  Renderer renderer{backend};
};

PlanViewer::PlanViewer(PlanViewerOptions options) : options_(std::move(options)) {
  std::vector<PlanRequest> replay;
  if (options_.replay) {
    replay = read_recording(*options_.replay);
  }
  const std::string plan_text = slurp(options_.plan);  // parsed here, and kept for Save
  const planning::PlanDescription plan = planning::parse_plan(plan_text, options_.plan);
  if (!options_.save) {
    options_.save = options_.plan.parent_path() / (options_.plan.stem().string() + "_moved.json");
  }
  window_ = open_window(options_.width, options_.height, "incise plan: " + plan.file.string(),
                        options_.replay ? 0 : 1, this);
  glfwSetScrollCallback(
      window_, [](GLFWwindow* window, double, double y) { viewer_of(window).on_scroll(y); });
  glfwSetMouseButtonCallback(window_, [](GLFWwindow* window, int button, int action, int) {
    viewer_of(window).on_mouse_button(button, action);
  });
  glfwSetKeyCallback(window_, [](GLFWwindow* window, int key, int, int action, int mods) {
    if (action == GLFW_PRESS || action == GLFW_REPEAT) {
      viewer_of(window).on_key(key, mods);
    }
  });
  start_imgui(window_);
  graphics_ = std::make_unique<Graphics>();
  render_.draw_blade = false;
  render_.texture_period = 0.03;  // m: skin-sized tiles
  worker_ = std::make_unique<PlanWorker>(plan, plan_text, [] { glfwPostEmptyEvent(); });
  for (PlanRequest& request : replay) {
    recorded_.push_back(request);
    worker_->request(std::move(request));
  }
}

PlanViewer::~PlanViewer() {
  worker_.reset();
  graphics_.reset();
  close_window(window_);
}

double PlanViewer::aspect() const {
  int width = 0;
  int height = 0;
  glfwGetFramebufferSize(window_, &width, &height);
  return height > 0 ? static_cast<double>(width) / height : 1.0;
}

void PlanViewer::nudge(const Vec3& translate_mm, const Vec3& rotate_deg) {
  PlanRequest request;
  request.segment = selected_;
  request.translate_mm = translate_mm;
  request.rotate_deg = rotate_deg;
  recorded_.push_back(request);
  worker_->request(request);
}

void PlanViewer::save() {
  PlanRequest request;
  request.kind = PlanRequest::Kind::kSave;
  request.path = *options_.save;
  recorded_.push_back(request);
  worker_->request(request);
}

void PlanViewer::start_placing_plane() {
  placing_plane_ = true;
  bone_view_ = true;
  // Level on screen (the cut a surgeon draws first), tipped 30 degrees towards the camera so
  // that it shows as a disc rather than edge on.
  const Vec3 forward = (render_.camera.target - render_.camera.eye).normalized();
  Vec3 up = render_.camera.up - render_.camera.up.dot(forward) * forward;
  plane_normal_ = up.norm() > 0.0 ? up.normalized() : Vec3::UnitZ();
  tilt_plane(forward.cross(plane_normal_).normalized(), -30.0);
}

void PlanViewer::tilt_plane(const Vec3& axis, double degrees) {
  plane_normal_ =
      (Eigen::AngleAxisd(degrees * 3.14159265358979323846 / 180.0, axis) * plane_normal_)
          .normalized();
}

void PlanViewer::cut_at(const Vec3& point, const Vec3& normal) {
  PlanRequest request;
  request.kind = PlanRequest::Kind::kCut;
  request.point_mm = point * 1e3;
  request.normal = normal;
  recorded_.push_back(request);
  worker_->request(request);
  placing_plane_ = false;
}

std::vector<Vec3> PlanViewer::plane_disc() const {
  std::vector<Vec3> corners;
  if (!plane_point_) {
    return corners;
  }
  Bounds box;
  for (const Vec3& p : state_.bone_corners) {
    box.add(p);
  }
  const double radius = 0.6 * box.radius();
  const Vec3 n = plane_normal_.normalized();
  const Vec3 u = n.unitOrthogonal();
  const Vec3 v = n.cross(u);
  constexpr int kSides = 48;
  for (int i = 0; i < kSides; ++i) {
    const double a = 2.0 * 3.14159265358979323846 * i / kSides;
    const double b = 2.0 * 3.14159265358979323846 * (i + 1) / kSides;
    corners.push_back(*plane_point_);
    corners.push_back(*plane_point_ + radius * (std::cos(a) * u + std::sin(a) * v));
    corners.push_back(*plane_point_ + radius * (std::cos(b) * u + std::sin(b) * v));
  }
  return corners;
}

void PlanViewer::look_from(const Vec3& towards_camera) {
  Bounds box;
  for (const Vec3& p : state_.skin_before) {
    box.add(p);
  }
  if (state_.skin_before.empty()) {
    return;
  }
  const Vec3 up = std::abs(towards_camera.z()) > 0.9 ? Vec3::UnitY() : Vec3::UnitZ();
  render_.camera = fit_camera(box, aspect(), towards_camera, up, /*fill=*/1.2);
}

void PlanViewer::on_mouse_button(int button, int action) {
  // GLFW's left, right and middle buttons are 0, 1 and 2.
  if (action == GLFW_PRESS && button >= 0 && button < static_cast<int>(pressed_.size())) {
    pressed_[static_cast<std::size_t>(button)] = true;
  }
}

void PlanViewer::handle_keys() {
  const bool keyboard_free = !ImGui::GetIO().WantCaptureKeyboard;
  const int segments = static_cast<int>(state_.segment_volumes_mm3.size());
  while (!keys_.empty()) {
    const Key key = keys_.front();
    keys_.pop_front();
    if (!keyboard_free) {
      continue;
    }
    const bool shift = (key.mods & GLFW_MOD_SHIFT) != 0;
    const double mm = step_mm_;
    const double deg = step_deg_;
    const Vec3 forward = (render_.camera.target - render_.camera.eye).normalized();
    const Vec3 right = forward.cross(render_.camera.up).normalized();
    auto move_along = [&](const Vec3& axis) {
      if (placing_plane_) {
        // The plane being placed tilts instead: left and right about the view, up and down
        // about the screen's horizontal.
        if (axis.x() != 0.0) {
          tilt_plane(forward, axis.x() * deg);
        } else if (axis.y() != 0.0) {
          tilt_plane(right, axis.y() * deg);
        }
        return;
      }
      if (shift) {
        nudge(Vec3::Zero(), deg * axis);
      } else {
        nudge(mm * axis, Vec3::Zero());
      }
    };
    switch (key.key) {
      case GLFW_KEY_TAB:
        if (segments > 0) {
          selected_ = (selected_ + (shift ? segments - 1 : 1)) % segments;
        }
        break;
      case GLFW_KEY_RIGHT:
        move_along(Vec3::UnitX());
        break;
      case GLFW_KEY_LEFT:
        move_along(-Vec3::UnitX());
        break;
      case GLFW_KEY_UP:
        move_along(Vec3::UnitY());
        break;
      case GLFW_KEY_DOWN:
        move_along(-Vec3::UnitY());
        break;
      case GLFW_KEY_PAGE_UP:
        move_along(Vec3::UnitZ());
        break;
      case GLFW_KEY_PAGE_DOWN:
        move_along(-Vec3::UnitZ());
        break;
      case GLFW_KEY_B:
        bone_view_ = !bone_view_;
        break;
      case GLFW_KEY_1:
        look_from(-Vec3::UnitY());
        break;
      case GLFW_KEY_2:
        look_from(Vec3::UnitX());
        break;
      case GLFW_KEY_3:
        look_from(Vec3::UnitZ());
        break;
      case GLFW_KEY_O:
        if (placing_plane_) {
          placing_plane_ = false;
        } else {
          start_placing_plane();
        }
        break;
      case GLFW_KEY_ENTER:
      case GLFW_KEY_KP_ENTER:
        if (placing_plane_ && plane_point_) {
          cut_at(*plane_point_, plane_normal_);
        }
        break;
      case GLFW_KEY_S:
        save();
        break;
      case GLFW_KEY_P:
        save_screenshot("incise_plan_screenshot.png");
        break;
      case GLFW_KEY_ESCAPE:
        if (placing_plane_) {
          placing_plane_ = false;
        } else {
          glfwSetWindowShouldClose(window_, GLFW_TRUE);
        }
        break;
      default:
        break;
    }
  }
}

void PlanViewer::handle_mouse() {
  const ImGuiIO& io = ImGui::GetIO();
  double x = 0.0;
  double y = 0.0;
  glfwGetCursorPos(window_, &x, &y);
  int width = 1;
  int height = 1;
  glfwGetWindowSize(window_, &width, &height);
  // Held now, or pressed (and perhaps released already) since the last frame.
  const auto held = [this](int button) {
    const bool pressed = pressed_[static_cast<std::size_t>(button)];
    pressed_[static_cast<std::size_t>(button)] = false;
    return pressed || glfwGetMouseButton(window_, button) == GLFW_PRESS;
  };
  const bool left = held(GLFW_MOUSE_BUTTON_LEFT);
  const bool right = held(GLFW_MOUSE_BUTTON_RIGHT);
  const bool middle = held(GLFW_MOUSE_BUTTON_MIDDLE);
  const bool free = !io.WantCaptureMouse;
  if (scroll_ != 0.0 && free) {
    zoom(render_.camera, std::pow(0.9, scroll_));
  }
  scroll_ = 0.0;
  const double nx = 2.0 * x / std::max(width, 1) - 1.0;
  const double ny = 1.0 - 2.0 * y / std::max(height, 1);
  const Ray ray = cursor_ray(render_.camera, aspect(), nx, ny);
  if (placing_plane_ && !dragging_ && state_.ready) {
    // The plane follows the bone point under the cursor.
    if (const auto hit = pick_bone(ray)) {
      plane_point_ = hit->point;
    }
  }
  if (free && left && !dragging_ && !drag_anchor_ && bone_view_ && !placing_plane_ &&
      state_.ready && !state_.busy) {
    // A press on the selected segment takes it: to move it, or with Shift to turn it.
    if (const auto hit = pick_bone(ray); hit && state_.bone_segment[hit->triangle] == selected_) {
      drag_anchor_ = hit->point;
      drag_offset_ = Vec3::Zero();
      drag_turns_ = glfwGetKey(window_, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ||
                    glfwGetKey(window_, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS;
      drag_from_ = ray;
      drag_angle_ = 0.0;
    }
  }
  if (drag_anchor_) {
    if (left && drag_turns_) {
      drag_angle_ = turn_on_screen(render_.camera, selected_centre(), drag_from_, ray);
    } else if (left) {
      drag_offset_ = point_on_anchor_plane(render_.camera, ray, *drag_anchor_) - *drag_anchor_;
    } else {
      // Released: the drag is a nudge (mm, or degrees about the axis towards the camera),
      // checked for contact and predicted.
      if (drag_turns_ && drag_angle_ != 0.0) {
        nudge(Vec3::Zero(),
              towards_camera(render_.camera) * (drag_angle_ * 180.0 / std::numbers::pi));
      } else if (!drag_turns_ && drag_offset_.norm() > 0.0) {
        nudge(drag_offset_ * 1e3, Vec3::Zero());
      }
      drag_anchor_.reset();
    }
    last_x_ = x;
    last_y_ = y;
    return;
  }
  if (free && (left || right || middle) && !dragging_) {
    dragging_ = true;
    moved_while_pressed_ = false;
  }
  if (dragging_) {
    const double dx = (x - last_x_) / std::max(height, 1);
    const double dy = (y - last_y_) / std::max(height, 1);
    if (dx != 0.0 || dy != 0.0) {
      moved_while_pressed_ = true;
    }
    const bool shift = glfwGetKey(window_, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS;
    if (middle || (right && shift)) {
      pan(render_.camera, -dx, dy);
    } else if (left || right) {
      orbit(render_.camera, -3.0 * dx, 3.0 * dy);
    }
    if (!left && !right && !middle) {
      dragging_ = false;
      if (!moved_while_pressed_ && bone_view_) {
        // A click on the bone cuts it there (placing a plane) or picks its segment.
        if (const auto hit = pick_bone(ray)) {
          if (placing_plane_) {
            cut_at(hit->point, plane_normal_);
          } else {
            selected_ = state_.bone_segment[hit->triangle];
          }
        }
      }
    }
  }
  last_x_ = x;
  last_y_ = y;
}

Vec3 PlanViewer::selected_centre() const {
  const auto s = static_cast<std::size_t>(selected_);
  return state_.segment_centres[s] + state_.poses[s].translation_mm * 1e-3;  // mm to m
}

std::optional<SurfaceHit> PlanViewer::pick_bone(const Ray& ray) {
  soup_.resize(state_.bone_corners.size() / 3);
  for (std::size_t t = 0; t < soup_.size(); ++t) {
    const auto first = static_cast<VertexId>(3 * t);
    soup_[t] = {first, first + 1, first + 2};
  }
  return pick_surface(ray, soup_, state_.bone_corners);
}

void PlanViewer::draw_scene() {
  int width = 0;
  int height = 0;
  glfwGetFramebufferSize(window_, &width, &height);
  if (width <= 0 || height <= 0) {
    return;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  render_.width = width;
  render_.height = height;
  if (!state_.ready) {
    glClearColor(38 / 255.0F, 42 / 255.0F, 52 / 255.0F, 1.0F);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    return;
  }
  const int segments = static_cast<int>(state_.segment_volumes_mm3.size());
  if (selected_ >= segments) {
    selected_ = 0;  // a plane made fewer segments... or another plan
  }
  // The disc of a plane being placed is part of the surface: its frames, and the first after
  // it, are new surfaces.
  if (state_.revision != drawn_revision_ || selected_ != drawn_selection_ ||
      bone_view_ != drawn_bone_view_ || placing_plane_ || drawn_placing_plane_) {
    ++surface_revision_;
    drawn_revision_ = state_.revision;
    drawn_selection_ = selected_;
    drawn_bone_view_ = bone_view_;
    drawn_placing_plane_ = placing_plane_;
  }
  // Spans into state_ and these members, which stay until the next draw.
  std::vector<Triangle>& soup = soup_;
  std::vector<double>& scalars = scalars_;
  std::vector<std::uint8_t>& exterior = exterior_;
  RenderInput input;
  input.surface_revision = surface_revision_;
  if (bone_view_) {
    // The bone: the selected segment red, the moved ones light, the others grey-blue.
    soup.resize(state_.bone_corners.size() / 3);
    scalars.assign(state_.bone_corners.size(), 0.0);
    for (std::size_t t = 0; t < soup.size(); ++t) {
      const auto first = static_cast<VertexId>(3 * t);
      soup[t] = {first, first + 1, first + 2};
      const int segment = state_.bone_segment[t];
      const SegmentPose& pose = state_.poses[static_cast<std::size_t>(segment)];
      const bool moved = pose.translation_mm != Vec3::Zero() || pose.rotation != Mat3::Identity();
      const double value = segment == selected_ ? 1.0 : moved ? 0.6 : 0.25;
      for (int c = 0; c < 3; ++c) {
        scalars[3 * t + static_cast<std::size_t>(c)] = value;
      }
    }
    input.rest_positions = state_.bone_corners;
    input.positions = state_.bone_corners;
    if (drag_anchor_) {
      // The segment being dragged, where the cursor has taken it (checked on release): moved,
      // or turned about its centre as the nudge will turn it.
      const Vec3 centre = selected_centre();
      const Mat3 turn =
          Eigen::AngleAxisd(drag_turns_ ? drag_angle_ : 0.0, towards_camera(render_.camera))
              .toRotationMatrix();
      dragged_ = state_.bone_corners;
      for (std::size_t t = 0; t < soup.size(); ++t) {
        if (state_.bone_segment[t] == selected_) {
          for (std::size_t c = 0; c < 3; ++c) {
            Vec3& corner = dragged_[3 * t + c];
            corner = drag_turns_ ? Vec3(centre + turn * (corner - centre)) : corner + drag_offset_;
          }
        }
      }
      input.positions = dragged_;
    }
    if (placing_plane_ && plane_point_) {
      // The plane being placed: a pale disc over the bone.
      shown_.assign(input.positions.begin(), input.positions.end());
      const std::vector<Vec3> disc = plane_disc();
      for (std::size_t c = 0; c < disc.size(); c += 3) {
        const auto first = static_cast<VertexId>(shown_.size());
        shown_.insert(shown_.end(), disc.begin() + static_cast<std::ptrdiff_t>(c),
                      disc.begin() + static_cast<std::ptrdiff_t>(c + 3));
        soup.push_back({first, first + 1, first + 2});
      }
      scalars.resize(shown_.size(), 0.5);
      input.rest_positions = shown_;
      input.positions = shown_;
    }
    exterior.assign(soup.size(), 0);
    input.triangles = soup;
    render_.scalar_range = {0.0, 1.0};
  } else {
    scalars.resize(state_.skin_after.size());
    for (std::size_t i = 0; i < scalars.size(); ++i) {
      scalars[i] = (state_.skin_after[i] - state_.skin_before[i]).norm() * 1e3;  // mm
    }
    exterior.assign(state_.skin_triangles.size(), 0);
    input.triangles = state_.skin_triangles;
    input.rest_positions = state_.skin_before;
    input.positions = state_.skin_after;
    render_.scalar_range = {0.0, std::max(state_.largest_displacement_mm, 1e-9)};
  }
  input.on_cut = exterior;
  input.scalars = scalars;
  graphics_->renderer.render(input, render_);
}

void PlanViewer::draw_panel() {
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_Once);
  // As tall as what it holds (it grows once the plan is prepared), 420 pixels wide.
  ImGui::SetNextWindowSizeConstraints(ImVec2(420, 0), ImVec2(420, 10000));
  ImGui::Begin("plan", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::TextWrapped("%s", options_.plan.string().c_str());
  ImGui::Separator();
  if (state_.busy) {
    ImGui::TextColored(ImVec4(1.0F, 0.8F, 0.3F, 1.0F), "%s",
                       state_.ready ? "predicting..." : "preparing...");
  }
  ImGui::TextWrapped("%s", state_.status.c_str());
  if (state_.ready) {
    // The colour bar: ParaView's Cool to Warm from 0 mm to the largest displacement.
    ImGui::Separator();
    if (bone_view_) {
      ImGui::Text("bone: selected segment red, moved light, still blue-grey (B: the skin)");
      ImGui::Text("drag the selected segment to move it, Shift+drag to turn it");
    } else {
      ImGui::Text("skin displacement (mm)  (B: the bone)");
      ImDrawList* draw = ImGui::GetWindowDrawList();
      const ImVec2 at = ImGui::GetCursorScreenPos();
      const float width = 300.0F;
      const float height = 14.0F;
      for (int i = 0; i < 8; ++i) {
        const auto colour = [](double t) {
          const Rgba c = cool_to_warm(t);
          return IM_COL32(c.r, c.g, c.b, 255);
        };
        draw->AddRectFilledMultiColor(
            ImVec2(at.x + width * static_cast<float>(i) / 8, at.y),
            ImVec2(at.x + width * static_cast<float>(i + 1) / 8, at.y + height), colour(i / 8.0),
            colour((i + 1) / 8.0), colour((i + 1) / 8.0), colour(i / 8.0));
      }
      ImGui::Dummy(ImVec2(width, height));
      ImGui::Text("0");
      const std::string largest = fmt::format("{:.2f} mm", state_.largest_displacement_mm);
      ImGui::SameLine(width - ImGui::CalcTextSize(largest.c_str()).x + 8.0F);
      ImGui::Text("%s", largest.c_str());
    }
    ImGui::Separator();
    ImGui::Text("osteotomy planes: %d", state_.osteotomies);
    if (placing_plane_) {
      ImGui::TextWrapped(
          "placing a plane (the pale disc): it goes through the bone under the cursor; the arrows "
          "tilt it by the step in degrees; click the bone or press Enter to cut there.");
      if (ImGui::Button("Cancel (O)")) {
        placing_plane_ = false;
      }
    } else if (ImGui::Button("Place an osteotomy plane (O)")) {
      start_placing_plane();
    }
    ImGui::Separator();
    ImGui::Text("segments (Tab; click one in the bone view)");
    for (std::size_t s = 0; s < state_.segment_volumes_mm3.size(); ++s) {
      const SegmentPose& pose = state_.poses[s];
      const double degrees = Eigen::AngleAxisd(pose.rotation).angle() * 180.0 / 3.14159265358979;
      const std::string row =
          fmt::format("{}: {:.0f} mm^3, moved ({:.1f}, {:.1f}, {:.1f}) mm, turned {:.1f} deg", s,
                      state_.segment_volumes_mm3[s], pose.translation_mm.x(),
                      pose.translation_mm.y(), pose.translation_mm.z(), degrees);
      if (ImGui::Selectable(row.c_str(), static_cast<int>(s) == selected_)) {
        selected_ = static_cast<int>(s);
      }
    }
    ImGui::Separator();
    ImGui::SliderFloat("step (mm)", &step_mm_, 0.1F, 5.0F, "%.1f");
    ImGui::SliderFloat("step (deg)", &step_deg_, 0.1F, 10.0F, "%.1f");
    const char* names[3] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
      const Vec3 unit = Vec3::Unit(axis);
      ImGui::PushID(axis);
      if (ImGui::Button(fmt::format("-{}", names[axis]).c_str())) {
        nudge(-step_mm_ * unit, Vec3::Zero());
      }
      ImGui::SameLine();
      if (ImGui::Button(fmt::format("+{}", names[axis]).c_str())) {
        nudge(step_mm_ * unit, Vec3::Zero());
      }
      ImGui::SameLine();
      if (ImGui::Button(fmt::format("turn -{}", names[axis]).c_str())) {
        nudge(Vec3::Zero(), -step_deg_ * unit);
      }
      ImGui::SameLine();
      if (ImGui::Button(fmt::format("turn +{}", names[axis]).c_str())) {
        nudge(Vec3::Zero(), step_deg_ * unit);
      }
      ImGui::PopID();
    }
    ImGui::Separator();
    if (ImGui::Button("front (1)")) {
      look_from(-Vec3::UnitY());
    }
    ImGui::SameLine();
    if (ImGui::Button("side (2)")) {
      look_from(Vec3::UnitX());
    }
    ImGui::SameLine();
    if (ImGui::Button("above (3)")) {
      look_from(Vec3::UnitZ());
    }
    ImGui::SameLine();
    if (ImGui::Button("Save (S)")) {
      save();
    }
    ImGui::TextWrapped("Save writes %s", options_.save->string().c_str());
  }
  ImGui::End();
}

void PlanViewer::save_screenshot(const std::filesystem::path& path) {
  write_png(path, read_window_picture(window_));
}

int PlanViewer::run() {
  // A replay closes a few drawn frames after its requests have run (the panel lays itself out
  // in its first frames): the picture is of the last prediction, panel and all.
  int frames_since_replayed = -1;
  while (glfwWindowShouldClose(window_) == 0) {
    const bool busy = !worker_->idle();
    glfwWaitEventsTimeout(busy || !keys_.empty() || frames_since_replayed >= 0 ? 0.02 : 0.25);
    state_ = worker_->state();
    if (state_.ready && !camera_fitted_) {
      look_from(-Vec3::UnitY());
      camera_fitted_ = true;
    }
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    if (!options_.replay) {
      handle_keys();
      handle_mouse();
    } else if (frames_since_replayed < 0 && worker_->idle()) {
      frames_since_replayed = 0;
    }
    draw_scene();
    draw_panel();
    ImGui::Render();
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    const bool replayed = frames_since_replayed >= 0 && ++frames_since_replayed > 3;
    if (options_.screenshot && (replayed || glfwWindowShouldClose(window_) != 0)) {
      save_screenshot(*options_.screenshot);
    }
    glfwSwapBuffers(window_);
    if (replayed || (!state_.error.empty() && options_.replay)) {
      break;
    }
  }
  const PlanState last = worker_->state();
  if (options_.record) {
    nlohmann::json requests = nlohmann::json::array();
    for (const PlanRequest& request : recorded_) {
      requests.push_back(to_json(request));
    }
    write_file_atomically(
        *options_.record,
        nlohmann::json{{"plan", options_.plan.string()}, {"requests", requests}}.dump(2) + "\n");
  }
  if (!last.error.empty()) {
    std::cerr << "error: " << last.error << "\n";
    return 2;
  }
  std::cout << fmt::format(
      "incise plan --view: {} predictions; largest skin displacement {:.17g} "
      "mm; {}\n",
      last.predictions, last.largest_displacement_mm, last.status);
  return 0;
}

}  // namespace incise::app
