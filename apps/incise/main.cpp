// incise: command line for cutting and deforming 3-D soft tissue.

#include <csignal>
#include <iostream>
#include <map>

#include "commands.hpp"
#include "incise/core/error.hpp"

int main(int argc, char** argv) {
  // A pipe whose reader died (ffmpeg writing a video) is an error to report, not a kill.
  std::signal(SIGPIPE, SIG_IGN);
  CLI::App app{"incise: interactive cutting and deformation of 3-D soft tissue"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "incise 0.1.0");
  std::map<CLI::App*, incise::app::Runner> runners;
  auto add = [&](incise::app::Runner (*factory)(CLI::App&)) {
    const std::size_t before = app.get_subcommands({}).size();
    incise::app::Runner runner = factory(app);
    runners[app.get_subcommands({})[before]] = std::move(runner);
  };
  add(incise::app::add_info_command);
  add(incise::app::add_convert_command);
  add(incise::app::add_generate_command);
  add(incise::app::add_mesh_command);
  add(incise::app::add_run_command);
  add(incise::app::add_cut_command);
  add(incise::app::add_view_command);
  add(incise::app::add_plan_command);
  add(incise::app::add_soak_command);
#ifdef INCISE_HAVE_OPENIGTLINK
  add(incise::app::add_serve_command);
  add(incise::app::add_device_command);
#endif
  incise::app::add_help_notes(app);
  if (argc == 1) {
    incise::app::print_start_here();
    return incise::app::kExitError;  // a command is needed
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    // --help and --version exit 0; a bad command line is an error like any other (exit 2),
    // not CLI11's own codes.
    return app.exit(error) == 0 ? 0 : incise::app::kExitError;
  }
  try {
    for (auto& [command, runner] : runners) {
      if (command->parsed()) {
        return runner();
      }
    }
  } catch (const incise::Error& error) {
    std::cerr << "error: " << error.what() << "\n";
    return incise::app::kExitError;
  } catch (const std::exception& error) {
    std::cerr << "error: " << error.what() << "\n";
    return incise::app::kExitError;
  }
  return incise::app::kExitError;
}
