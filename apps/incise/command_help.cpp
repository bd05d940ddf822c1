// What every command's help ends with: its units and examples (the examples run in this order,
// in one folder holding a link to scenes/, by the test Cli.EveryHelpExampleRuns), and what
// `incise` alone prints: where to start.

#include <iostream>
#include <string>
#include <vector>

#include "commands.hpp"

namespace incise::app {
namespace {

struct HelpNotes {
  const char* command;  // "generate box" for a subcommand of a subcommand
  const char* units;
  std::vector<std::string> examples;
};

const std::vector<HelpNotes>& help_notes() {
  static const std::vector<HelpNotes> notes = {
      {"generate box",
       "m (cells: counts along x, y, z)",
       {"incise generate box --cells 4 6 4 --size 0.04 0.06 0.04 -o block.vtu"}},
      {"info",
       "the mesh's own length unit (incise never rescales): volumes in it cubed; exit 1 when "
       "the mesh is invalid",
       {"incise info block.vtu", "incise info block.vtu --json"}},
      {"convert",
       "coordinates copied as they are (no rescaling)",
       {"incise convert block.vtu block.msh", "incise convert block.vtu block_surface.obj"}},
      {"mesh",
       "the surface's length unit; --max-volume in that unit cubed",
       {"incise mesh block_surface.obj -o remeshed.vtu --max-volume 1e-7"}},
      {"run",
       "SI: m, s, kg, Pa, N (scene keys and their units: scenes/README.md)",
       {"incise run scenes/default.json --frames 40 --out run --record-tool blade.csv"}},
      {"cut",
       "the blade path's t in s, its positions in the mesh's unit (--unit names it)",
       {"incise cut block.vtu --blade blade.csv -o cut.vtu --unit m"}},
      {"plan",
       "mm and degrees (plan keys: scenes/README.md); the report's times in s",
       {"incise plan scenes/plan_headsq.json --out plan"}},
      {"soak",
       "SI, as the scenes; --minutes in minutes",
       {"incise soak --cuts 2 --poses 10 --out soak"}},
      {"view",
       "SI, as the scene; needs a display (Xvfb will do)",
       {"incise view scenes/default.json"}},
      {"serve",
       "the scene in SI; on the wire millimetres (TRANSFORM poses, POLYDATA surfaces), as Slicer, "
       "and forces in N (SENSOR); needs a device",
       {"incise serve scenes/default.json --port 18944 --out served"}},
      {"device",
       "the blade path's t in s, positions in m; forces logged in N",
       {"incise device blade.csv --port 18944 --log forces.csv"}},
  };
  return notes;
}

CLI::App* find_command(CLI::App& app, const std::string& path) {
  CLI::App* command = &app;
  std::size_t start = 0;
  while (command != nullptr && start < path.size()) {
    const std::size_t end = std::min(path.find(' ', start), path.size());
    CLI::App* next = nullptr;
    for (CLI::App* sub : command->get_subcommands({})) {
      if (sub->get_name() == path.substr(start, end - start)) {
        next = sub;
      }
    }
    command = next;
    start = end + 1;
  }
  return command;
}

}  // namespace

void add_help_notes(CLI::App& app) {
  for (const HelpNotes& notes : help_notes()) {
    CLI::App* command = find_command(app, notes.command);
    if (command == nullptr) {
      continue;  // not built here (serve and device need OpenIGTLink)
    }
    std::string footer = std::string("Units: ") + notes.units;
    for (const std::string& example : notes.examples) {
      footer += "\nExample: " + example;
    }
    command->footer(footer);
  }
}

void print_start_here() {
  std::cout
      << "incise: interactive cutting and deformation of 3-D soft tissue (SI units: m, s, kg, "
         "Pa, N; planning in mm)\n\n"
         "Start here:\n"
         "  incise run                             cut the default block, write a ParaView "
         "series (out/default/default.pvd)\n"
         "  incise view                            the same in a window: drag the mouse to cut\n"
         "  incise plan scenes/plan_headsq.json    predict a face from a CT after a bone cut\n"
         "  incise serve                           let a haptic device or 3D Slicer drive the "
         "blade over OpenIGTLink\n\n"
         "incise --help lists every command; incise COMMAND --help gives its options, units "
         "and an example.\n";
}

}  // namespace incise::app
