// incise convert IN OUT [--fix-orientation] [--fix-slivers]

#include <fmt/format.h>

#include <iostream>

#include "commands.hpp"
#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/sliver_repair.hpp"
#include "incise/mesh/validate.hpp"

namespace incise::app {

Runner add_convert_command(CLI::App& app) {
  auto* command = app.add_subcommand(
      "convert", "Convert a mesh between formats (output format from the extension)");
  auto input = std::make_shared<std::string>();
  auto output = std::make_shared<std::string>();
  auto fix = std::make_shared<bool>(false);
  command->add_option("input", *input, "Input mesh or surface")
      ->required()
      ->check(CLI::ExistingFile);
  command
      ->add_option("output", *output, "Output: .msh, .vtu, .mesh, .obj, .node (.vtp for surfaces)")
      ->required();
  command->add_flag("--fix-orientation", *fix, "Flip inverted tetrahedra to positive orientation");
  auto slivers = std::make_shared<bool>(false);
  command->add_flag("--fix-slivers", *slivers,
                    "Remove flat tetrahedra and slivers by collapsing an edge of each (an interior "
                    "vertex onto its neighbour; a boundary one only where the boundary stays "
                    "within a thousandth of the sliver's size), saying what it did");
  return [input, output, fix, slivers]() {
    const RawMesh raw = read_raw_mesh(*input);
    if (raw.tets.empty()) {
      // A surface: convert it as one.
      const SurfaceMesh surface = read_surface(*input);
      const std::string extension = std::filesystem::path(*output).extension().string();
      if (extension == ".obj") {
        write_obj(*output, surface.points, surface.triangles);
      } else if (extension == ".vtp") {
        write_vtp(*output, surface.points, surface.triangles);
      } else {
        throw InputError(*input, 0, "holds only a surface; convert it to .obj or .vtp");
      }
      std::cerr << fmt::format("wrote {} ({} points, {} triangles)\n", *output,
                               surface.points.size(), surface.triangles.size());
      return 0;
    }
    TetMeshReadResult read = read_tet_mesh(*input);
    for (const std::string& note : read.notes) {
      std::cerr << "note: " << note << "\n";
    }
    TetMesh mesh = std::move(read.mesh);
    ValidationReport report = validate(mesh);
    if (*fix && !report.inverted_tets.empty()) {
      std::vector<Tet> tets(mesh.tets().begin(), mesh.tets().end());
      for (TetId t : report.inverted_tets) {
        std::swap(tets[t][2], tets[t][3]);
      }
      const std::size_t flipped = report.inverted_tets.size();
      mesh = TetMesh(std::vector<Vec3>(mesh.rest_positions().begin(), mesh.rest_positions().end()),
                     std::move(tets));
      report = validate(mesh);
      std::cerr << fmt::format("flipped {} inverted tetrahedra\n", flipped);
    }
    if (*slivers) {
      const SliverRepairResult fixed = fix_slivers(mesh);
      report = validate(mesh);
      std::cerr << fmt::format(
          "fix-slivers: {} flat and {} slivers before, {} edges collapsed, {} flat and {} slivers "
          "left; the boundary moved by at most {:.3g} (mesh units)\n",
          fixed.flat_before, fixed.slivers_before, fixed.collapses, fixed.flat_after,
          fixed.slivers_after, fixed.boundary_shift);
    }
    if (!report.ok()) {
      std::cerr << "warning: the mesh is not valid:\n" << report.describe();
    }
    write_tet_mesh(*output, mesh);
    std::cerr << fmt::format("wrote {} ({} vertices, {} tetrahedra)\n", *output,
                             mesh.vertex_count(), mesh.tet_count());
    return 0;
  };
}

}  // namespace incise::app
