#pragma once
// Sub-commands of the incise command line. Each registers itself on the CLI11 app and
// returns the process exit code when run.

#include <CLI/CLI.hpp>
#include <functional>

namespace incise::app {

/// Exit codes: 0 success, 1 the input is invalid (info), 2 an error stopped the command.
inline constexpr int kExitInvalid = 1;
inline constexpr int kExitError = 2;
/// The simulation diverged (NaN, blow-up); frames written before stay valid.
inline constexpr int kExitDiverged = 3;

using Runner = std::function<int()>;

Runner add_info_command(CLI::App& app);
Runner add_convert_command(CLI::App& app);
Runner add_generate_command(CLI::App& app);
Runner add_mesh_command(CLI::App& app);
Runner add_run_command(CLI::App& app);
Runner add_cut_command(CLI::App& app);
Runner add_view_command(CLI::App& app);
Runner add_serve_command(CLI::App& app);
Runner add_device_command(CLI::App& app);
Runner add_plan_command(CLI::App& app);
Runner add_soak_command(CLI::App& app);

/// Ends each command's help with its units and examples (after every command is added).
void add_help_notes(CLI::App& app);
/// What `incise` with no arguments prints: where to start.
void print_start_here();

}  // namespace incise::app
