// The viewer's Dear ImGui panels: simulation controls, view, settings, mesh statistics and
// the per-stage timing plot (the seed's Table 1 stages, live).

#include <imgui.h>

#include <algorithm>
#include <array>
#include <vector>

#include "incise/solve/linear_solvers.hpp"
#include "viewer.hpp"

namespace incise::app {

namespace {

/// A plot of the last frames of one stage (ms) with its latest value.
void stage_plot(const char* label, const std::deque<float>& series, float scale_max) {
  const std::vector<float> values(series.begin(), series.end());
  const float latest = values.empty() ? 0.0F : values.back();
  char overlay[64];
  std::snprintf(overlay, sizeof(overlay), "%s %.2f ms", label, static_cast<double>(latest));
  ImGui::PlotLines(label, values.data(), static_cast<int>(values.size()), 0, overlay, 0.0F,
                   scale_max, ImVec2(0, 48));
}

}  // namespace

void Viewer::draw_panels() {
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSize(ImVec2(330, 0), ImGuiCond_FirstUseEver);
  ImGui::Begin("incise");
  ImGui::Text("%s", scene_.file.empty() ? "default scene" : scene_.file.filename().c_str());
  ImGui::Text("frame %d   t = %.3f s", snapshot_->frame, snapshot_->time);
  const bool playing = thread_->playing();
  if (ImGui::Button(playing ? "Pause (space)" : "Play (space)")) {
    thread_->set_playing(!playing);
    action(playing ? "pause" : "play");
  }
  ImGui::SameLine();
  if (ImGui::Button("Step (N)")) {
    action("step");
    thread_->step_once();
  }
  ImGui::SameLine();
  if (ImGui::Button("Reset (R)")) {
    action("reset");
    start_engine();
  }
  if (replay_) {
    ImGui::TextColored(ImVec4(1, 0.8F, 0.3F, 1), "replaying a recorded session");
  } else if (hand_ != nullptr && !hand_->taken()) {
    ImGui::TextWrapped("The scene's own blade path plays; press on the body to take the scalpel.");
  }

  ImGui::Separator();
  ImGui::TextUnformatted("View");
  int mode = static_cast<int>(render_.mode);
  const int before = mode;
  ImGui::RadioButton("faces (F)", &mode, static_cast<int>(RenderMode::kFaces));
  ImGui::SameLine();
  ImGui::RadioButton("wire (G)", &mode, static_cast<int>(RenderMode::kWire));
  ImGui::SameLine();
  ImGui::RadioButton("cut (C)", &mode, static_cast<int>(RenderMode::kCut));
  if (mode != before) {
    render_.mode = static_cast<RenderMode>(mode);
    action("mode", std::string(name_of(render_.mode)));
  }
  if (ImGui::Checkbox("active tetrahedra (H)", &highlight_active_)) {
    action("highlight", highlight_active_ ? "on" : "off");
  }
  if (ImGui::Button("Screenshot (P)")) {
    pending_screenshot_ = "incise_screenshot.png";
  }
  float depth_mm = static_cast<float>(1e3 * depth_);
  if (ImGui::SliderFloat("blade depth (mm)", &depth_mm, 0.5F,
                         static_cast<float>(2e3 * body_radius_), "%.1f")) {
    depth_ = 1e-3 * depth_mm;
  }

  if (ImGui::CollapsingHeader("Settings (applied with a reset)") && !replay_) {
    ImGui::InputFloat("Young's modulus (Pa)", &settings_.young_modulus, 0, 0, "%.0f");
    ImGui::InputFloat("Poisson's ratio", &settings_.poisson_ratio, 0, 0, "%.3f");
    ImGui::InputFloat("density (kg/m^3)", &settings_.density, 0, 0, "%.0f");
    const std::array<IntegratorKind, 6> integrators{
        IntegratorKind::kExplicitEuler, IntegratorKind::kSymplecticEuler,
        IntegratorKind::kRungeKutta4,   IntegratorKind::kHierarchicalRungeKutta4,
        IntegratorKind::kBackwardEuler, IntegratorKind::kStatic};
    const std::string current(name_of(static_cast<IntegratorKind>(settings_.integrator)));
    if (ImGui::BeginCombo("integrator", current.c_str())) {
      for (IntegratorKind kind : integrators) {
        const std::string name(name_of(kind));
        if (ImGui::Selectable(name.c_str(), static_cast<int>(kind) == settings_.integrator)) {
          settings_.integrator = static_cast<int>(kind);
        }
      }
      ImGui::EndCombo();
    }
    ImGui::InputFloat("dt (s)", &settings_.dt, 0, 0, "%.5f");
    if (preconditioner_applies()) {
      // two-level pays off on large or cut bodies (BENCHMARKS.md); block-Jacobi on small ones.
      const std::array<Preconditioner, 5> preconditioners{
          Preconditioner::kBlockJacobi, Preconditioner::kTwoLevel, Preconditioner::kJacobi,
          Preconditioner::kIncompleteCholesky, Preconditioner::kNone};
      const std::string chosen = to_string(static_cast<Preconditioner>(settings_.preconditioner));
      if (ImGui::BeginCombo("preconditioner", chosen.c_str())) {
        for (Preconditioner preconditioner : preconditioners) {
          if (ImGui::Selectable(to_string(preconditioner).c_str(),
                                static_cast<int>(preconditioner) == settings_.preconditioner)) {
            settings_.preconditioner = static_cast<int>(preconditioner);
          }
        }
        ImGui::EndCombo();
      }
    }
    ImGui::RadioButton("minimal split", &settings_.split, static_cast<int>(SplitMode::kMinimal));
    ImGui::SameLine();
    ImGui::RadioButton("generic split", &settings_.split, static_cast<int>(SplitMode::kGeneric));
    if (ImGui::Button("Apply and reset")) {
      apply_settings();
    }
  }

  if (ImGui::CollapsingHeader("Mesh", ImGuiTreeNodeFlags_DefaultOpen)) {
    const SurfaceTopology& surface = *snapshot_->surface;
    std::size_t cut = 0;
    for (std::uint8_t mark : surface.on_cut) {
      cut += mark;
    }
    ImGui::Text("%zu vertices, %zu tetrahedra", snapshot_->positions.size(), snapshot_->tets);
    ImGui::Text("%zu surface triangles, %zu on the cut", surface.triangles.size(), cut);
    ImGui::Text("model %s, %s", std::string(name_of(scene_.model_type)).c_str(),
                integrator_name_.c_str());
    ImGui::Text("active tetrahedra %zu", snapshot_->active.size());
  }

  if (ImGui::CollapsingHeader("Timing (ms per frame)", ImGuiTreeNodeFlags_DefaultOpen)) {
    float highest = 1.0F;
    for (const auto* series : {&timing_.cd, &timing_.gc, &timing_.rx, &timing_.rd}) {
      for (float value : *series) {
        highest = std::max(highest, value);
      }
    }
    stage_plot("cd", timing_.cd, highest);
    stage_plot("gc", timing_.gc, highest);
    stage_plot("rx", timing_.rx, highest);
    stage_plot("rd", timing_.rd, highest);
    ImGui::Text("%.0f frames/s drawn", static_cast<double>(ImGui::GetIO().Framerate));
  }
  if (!message_.empty()) {
    ImGui::TextWrapped("%s", message_.c_str());
  }
  ImGui::TextDisabled(
      "left: cut on the body, orbit beside it; right: orbit; middle or "
      "shift+right: pan; wheel: zoom, blade depth while cutting");
  ImGui::End();
}

}  // namespace incise::app
