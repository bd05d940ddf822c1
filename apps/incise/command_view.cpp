// incise view [SCENE] [--replay FILE] [--record FILE] [--screenshot OUT.png] [--exit-after N]
// [--size WxH] [--mode faces|wire|cut] [--out DIR] [--threads N]: the interactive viewer with the
// mouse scalpel (see viewer/viewer.hpp).

#include <memory>
#include <string>

#include "command_options.hpp"
#include "commands.hpp"
#include "incise/core/error.hpp"
#ifdef INCISE_HAVE_VIEWER
#include "viewer/viewer.hpp"
#endif

namespace incise::app {

Runner add_view_command(CLI::App& app) {
  auto* command = app.add_subcommand(
      "view",
      "Open the interactive viewer: play the scene, cut with the mouse (no scene: the "
      "default one)");
  auto scene_path = std::make_shared<std::string>();
  auto replay = std::make_shared<std::string>();
  auto record = std::make_shared<std::string>();
  auto screenshot = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto exit_after = std::make_shared<int>(-1);
  auto paced = std::make_shared<bool>(false);
  auto size = std::make_shared<std::string>("1280x800");
  auto mode = std::make_shared<std::string>("faces");
  auto threads = std::make_shared<int>(0);
  command->add_option("scene", *scene_path, "Scene file (JSON); see scenes/README.md")
      ->check(CLI::ExistingFile);
  command
      ->add_option("--replay", *replay,
                   "Play a recorded session (its scene and poses) instead of the scene")
      ->check(CLI::ExistingFile);
  command->add_option("--record", *record,
                      "Record the session (tool poses and UI actions per frame) to this file; "
                      "replay with incise run --replay or incise view --replay");
  command->add_option("--screenshot", *screenshot, "Save a picture of the view here at exit");
  auto* exit_after_option =
      command
          ->add_option("--exit-after", *exit_after,
                       "Play this many frames (the replay, else the scene's own path), then exit")
          ->check(CLI::NonNegativeNumber);
  command
      ->add_flag("--paced", *paced,
                 "With --exit-after: pace the physics to the scene's frame time, as when a user "
                 "watches (else it runs flat out); for measuring the frame rate a user sees")
      ->needs(exit_after_option);
  command->add_option("--size", *size, "Window size WxH (default 1280x800)");
  command->add_option("--mode", *mode, "faces, wire or cut (keys F, G, C)");
  command->add_option("--out", *out,
                      "Write the first and the last frame here as a ParaView series");
  add_threads_option(*command, *threads);
  return [=]() -> int {
#ifdef INCISE_HAVE_VIEWER
    const auto thread_limit = limit_threads(*threads);
    ViewerOptions options;
    if (!scene_path->empty()) {
      if (!replay->empty()) {
        throw InputError(*replay, 0,
                         "--replay plays the scene stored in the recording: give no scene file");
      }
      options.scene_file = *scene_path;
    }
    if (!replay->empty()) {
      options.replay = *replay;
    }
    if (!record->empty()) {
      options.record = *record;
    }
    if (!screenshot->empty()) {
      options.screenshot = *screenshot;
    }
    if (!out->empty()) {
      options.out = *out;
    }
    options.exit_after = *exit_after;
    options.paced = *paced;
    std::tie(options.width, options.height) = parse_size(*size);
    options.mode = parse_mode(*mode);
    Viewer viewer(options);
    return viewer.run();
#else
    throw InputError(
        "incise view: this incise was built without the viewer "
        "(-DINCISE_WITH_VIEWER=ON needs GLFW and Dear ImGui)");
#endif
  };
}

}  // namespace incise::app
