// incise cut MESH --blade PATH.csv [--method subdivision|xfem] -o OUT [--report R.json]
//   [--visual SURFACE --visual-out OUT.vtp] (xfem) [--unit m|cm|mm]

#include <fmt/format.h>

#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command_cut_xfem.hpp"
#include "commands.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/path_cut.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"

namespace incise::app {

Runner add_cut_command(CLI::App& app) {
  auto* command = app.add_subcommand("cut", "Cut a mesh along a blade path, without physics");
  auto mesh_path = std::make_shared<std::string>();
  auto blade_path = std::make_shared<std::string>();
  auto method = std::make_shared<std::string>("subdivision");
  auto output = std::make_shared<std::string>();
  auto report_path = std::make_shared<std::string>();
  auto snap = std::make_shared<double>(CutterOptions{}.snap_fraction);
  auto split = std::make_shared<std::string>("minimal");
  auto merge = std::make_shared<bool>(false);
  auto visual = std::make_shared<std::string>();
  auto visual_out = std::make_shared<std::string>();
  auto unit = std::make_shared<std::string>();
  command->add_option("mesh", *mesh_path, "Tetrahedral mesh")->required()->check(CLI::ExistingFile);
  command
      ->add_option("--blade", *blade_path,
                   "Blade path CSV: t,tip_x,tip_y,tip_z,base_x,base_y,base_z (s, and the "
                   "mesh's length unit)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--method", *method, "Cutting method")
      ->check(CLI::IsMember({"subdivision", "xfem"}))
      ->capture_default_str();
  command
      ->add_option("--split", *split,
                   "minimal: split only the edges the cut crosses; generic: the seed's generic "
                   "split of every cut tetrahedron first (for comparison)")
      ->check(CLI::IsMember({"minimal", "generic"}))
      ->capture_default_str();
  command->add_flag("--merge-blade-points", *merge,
                    "Leave out blade-line vertices within the snap distance of the cut (fewer "
                    "tetrahedra on finely sampled paths; the wound may trail a little more)");
  command->add_option("-o,--output", *output, "Cut mesh (.vtu, .msh, .mesh, .obj, .node)")
      ->required();
  command->add_option("--report", *report_path, "JSON report");
  command
      ->add_option(
          "--visual", *visual,
          "xfem: a visual surface (OBJ, STL, PLY, VTP) embedded in the mesh and cut with it")
      ->check(CLI::ExistingFile);
  command->add_option("--visual-out", *visual_out, "xfem: the cut visual surface (.vtp)");
  command
      ->add_option("--unit", *unit,
                   "The mesh's length unit, said in the report and the .vtu files (incise never "
                   "rescales; without it lengths are in \"mesh units\")")
      ->check(CLI::IsMember({"m", "cm", "mm"}));
  command
      ->add_option("--snap", *snap, "Snap crossings within this fraction of an edge to its vertex")
      ->check(CLI::Range(0.001, 0.49))
      ->capture_default_str();
  return [=]() {
    std::optional<double> length_unit_m;
    if (!unit->empty()) {
      length_unit_m = *unit == "m" ? 1.0 : (*unit == "cm" ? 1e-2 : 1e-3);
    }
    const std::string unit_name = length_unit_name(length_unit_m);
    if (*method == "xfem") {
      return cut_xfem(
          {*mesh_path, *blade_path, *output, *report_path, *visual, *visual_out, length_unit_m});
    }
    if (!visual->empty() || !visual_out->empty()) {
      throw InputError("--visual and --visual-out apply to --method xfem only");
    }
    TetMesh mesh = read_tet_mesh(*mesh_path).mesh;
    CutterOptions options;
    options.snap_fraction = *snap;
    options.split = *split == "generic" ? SplitMode::kGeneric : SplitMode::kMinimal;
    options.merge_blade_points = *merge;
    const PathCutResult cut = cut_along_path(mesh, read_blade_path(*blade_path), options,
                                             *mesh_path, *blade_path, unit_name);
    if (cut.slivers_in > 0) {
      std::cerr << fmt::format(
          "note: {} slivers (positive but tiny volume) in {}: cut as they are\n", cut.slivers_in,
          *mesh_path);
    }
    write_tet_mesh(*output, mesh, length_unit_m);
    std::cerr << cut.summary << "\n";
    if (!report_path->empty()) {
      write_file_atomically(*report_path, cut.report_json);
    }
    if (cut.invalid_poses > 0) {
      std::cerr << "error: the cut left an invalid mesh " << cut.first_problem << "\n";
      return kExitError;
    }
    return 0;
  };
}

}  // namespace incise::app
