// incise plan PLAN.json [--out DIR] [--render DIR [--size WxH]]: surgical planning (Teschner
// et al.), and pictures of the prediction.

#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <memory>

#include "command_options.hpp"
#include "commands.hpp"
#include "incise/core/error.hpp"
#include "incise/planning/plan.hpp"
#include "plan_pictures.hpp"
#ifdef INCISE_HAVE_GL
#include "incise/render/offscreen.hpp"
#endif
#ifdef INCISE_HAVE_VIEWER
#include "viewer/plan_viewer.hpp"
#endif

namespace incise::app {

namespace {

/// A bar on a terminal, one line per stage otherwise (logs, CI).
class PlanProgressBar {
 public:
  PlanProgressBar() : terminal_(isatty(fileno(stderr)) != 0) {}
  void operator()(const std::string& stage, double fraction) {
    if (terminal_) {
      const int width = 30;
      const int filled = static_cast<int>(width * fraction);
      std::cerr << fmt::format("\r[{}{}] {:3.0f} %  {:<40}",
                               std::string(static_cast<std::size_t>(filled), '#'),
                               std::string(static_cast<std::size_t>(width - filled), '.'),
                               100.0 * fraction, stage)
                << std::flush;
      if (fraction >= 1.0) {
        std::cerr << "\n";
      }
    } else if (stage != last_stage_ && stage.rfind("predicting (", 0) != 0) {
      std::cerr << fmt::format("plan: {}\n", stage);
    }
    last_stage_ = stage;
  }
  void interrupt() const {
    if (terminal_) {
      std::cerr << "\n";
    }
  }

 private:
  bool terminal_;
  std::string last_stage_;
};

}  // namespace

Runner add_plan_command(CLI::App& app) {
  auto* command = app.add_subcommand(
      "plan",
      "Surgical planning: layered soft tissue over bone, osteotomies and moves, the face "
      "predicted (lengths in mm; see scenes/README.md)");
  auto plan_path = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  command->add_option("plan", *plan_path, "Plan file (JSON)")->required()->check(CLI::ExistingFile);
  command->add_option("--out", *out, "Output folder (default: out/<plan name>)");
  auto render_dir = std::make_shared<std::string>();
  auto size = std::make_shared<std::string>("800x600");
  command->add_option(
      "--render", *render_dir,
      "Draw the skin before and after, and after coloured by its displacement (0 mm blue to "
      "the largest red), offscreen to DIR/skin_*.png");
  auto* size_option = command->add_option("--size", *size,
                                          "Picture (or window) size WxH in pixels (default "
                                          "800x600)");
  auto view = std::make_shared<bool>(false);
  auto record = std::make_shared<std::string>();
  auto replay = std::make_shared<std::string>();
  auto screenshot = std::make_shared<std::string>();
  auto save = std::make_shared<std::string>();
  auto* view_flag = command->add_flag(
      "--view", *view,
      "Open the plan in a window: pick bone segments and nudge them (mm, degrees), the face "
      "predicted after each move; Save writes the plan with the moves made");
  command->add_option("--record", *record, "With --view: record the nudges and saves (JSON)")
      ->needs(view_flag);
  command->add_option("--replay", *replay, "With --view: play a recording, then close")
      ->needs(view_flag)
      ->check(CLI::ExistingFile);
  command->add_option("--screenshot", *screenshot, "With --view: a picture of the window at exit")
      ->needs(view_flag);
  command
      ->add_option("--save", *save,
                   "With --view: where Save writes the plan with its moves (default "
                   "PLAN_moved.json beside the plan)")
      ->needs(view_flag);
  return [plan_path, out, render_dir, size, size_option, view, record, replay, screenshot, save]() {
    if (*view) {
#ifdef INCISE_HAVE_VIEWER
      PlanViewerOptions options;
      options.plan = *plan_path;
      const auto optional_path = [](const std::string& text) {
        return text.empty() ? std::nullopt : std::optional<std::filesystem::path>(text);
      };
      options.record = optional_path(*record);
      options.replay = optional_path(*replay);
      options.screenshot = optional_path(*screenshot);
      options.save = optional_path(*save);
      if (size_option->count() > 0) {
        std::tie(options.width, options.height) = parse_size(*size);
      }
      try {
        PlanViewer viewer(options);
        return viewer.run();
      } catch (const Error& error) {
        std::cerr << "error: " << error.what() << "\n";
        return kExitError;
      }
#else
      std::cerr << "error: incise plan --view: this incise was built without the viewer "
                   "(-DINCISE_WITH_VIEWER=ON needs GLFW and Dear ImGui)\n";
      return kExitError;
#endif
    }
    PlanProgressBar bar;
    try {
      // Picture options are checked before the plan runs.
      const auto [width, height] = parse_size(*size);
      std::unique_ptr<ImageRenderer> renderer;
      if (!render_dir->empty()) {
#ifdef INCISE_HAVE_GL
        renderer = std::make_unique<OffscreenRenderer>();
#else
        throw InputError("--render: this incise was built without OpenGL (-DINCISE_WITH_GL=ON)");
#endif
      }
      const planning::PlanDescription plan = planning::load_plan(*plan_path);
      const std::filesystem::path dir = out->empty()
                                            ? std::filesystem::path("out") / plan.file.stem()
                                            : std::filesystem::path(*out);
      const planning::PlanSummary summary = planning::run_plan(
          plan, dir, [&](const std::string& stage, double fraction) { bar(stage, fraction); });
      std::cout << fmt::format(
          "{}: {} points, {} springs, {} prisms; {} bone segments, {} moved\n"
          "residual force {:.3g} N before equilibrium, {:.3g} N after the prediction\n"
          "prediction: {} iterations ({} evaluations), {}, {:.2f} s\n"
          "largest skin displacement {:.3f} mm; total {:.2f} s\n"
          "outputs in {} (report.json; skin_after.vtp has the displacement in mm)\n",
          plan.file.string(), summary.points, summary.springs, summary.prisms, summary.segments,
          summary.moved_segments, summary.residual_force_before, summary.residual_force_after,
          summary.prediction.iterations, summary.prediction.evaluations,
          summary.prediction.converged ? "converged" : summary.prediction.message,
          summary.prediction.seconds, summary.max_displacement, summary.seconds, dir.string());
      if (renderer) {
        const PlanPictures pictures =
            write_plan_pictures(summary, *render_dir, width, height, *renderer);
        std::cout << fmt::format(
            "pictures in {}: skin_before.png, skin_after.png, skin_before_after.png, "
            "skin_displacement.png, _frontal.png, _lateral.png (0 mm blue to {:.3f} mm red)\n",
            *render_dir, pictures.largest_displacement_mm);
      }
      return summary.prediction.converged ? 0 : kExitDiverged;
    } catch (const InputError& error) {
      bar.interrupt();
      std::cerr << "error: " << error.what() << "\n";
      return kExitError;
    }
  };
}

}  // namespace incise::app
