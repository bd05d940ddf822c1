// incise mesh SURFACE -o OUT [--max-volume V] [--min-quality Q]: tetrahedralise with TetGen.

#include <fmt/format.h>

#include <chrono>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "incise/core/atomic_file.hpp"
#include "incise/core/timing.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/quality.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/meshing/repair_surface.hpp"
#include "incise/meshing/tetrahedralize.hpp"

namespace incise::app {

Runner add_mesh_command(CLI::App& app) {
  auto* command = app.add_subcommand(
      "mesh", "Tetrahedralise a closed triangle surface (OBJ, STL, PLY, VTK polydata) with TetGen");
  auto input = std::make_shared<std::string>();
  auto output = std::make_shared<std::string>();
  auto options = std::make_shared<TetrahedralizeOptions>();
  command->add_option("surface", *input, "Closed triangle surface")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("-o,--output", *output, "Output mesh (.msh, .vtu, .mesh, .obj, .node)")
      ->required();
  command
      ->add_option("--max-volume", options->max_volume,
                   "Largest tetrahedron volume, in the surface's units cubed (0: no bound)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command
      ->add_option("--min-quality", options->max_radius_edge_ratio,
                   "Quality bound: largest radius-edge ratio allowed (TetGen -q; >= 1.1, "
                   "smaller is better)")
      ->check(CLI::Range(1.1, 100.0))
      ->capture_default_str();
  command
      ->add_option("--min-dihedral", options->min_dihedral_deg,
                   "Smallest dihedral angle to aim for (degrees, 0-18)")
      ->check(CLI::Range(0.0, 18.0))
      ->capture_default_str();
  command->add_flag("--preserve-surface", options->preserve_surface,
                    "Keep the input triangles (no points added on the boundary)");
  auto remesh = std::make_shared<std::string>("auto");
  command
      ->add_option("--remesh", *remesh,
                   "Remesh the surface first: auto (when it has needle triangles), always, never")
      ->check(CLI::IsMember({"auto", "always", "never"}))
      ->capture_default_str();
  command
      ->add_option("--edge-length", options->remesh_edge_length,
                   "Target edge length when remeshing (0: the median input edge)")
      ->check(CLI::NonNegativeNumber);
  auto largest = std::make_shared<bool>(false);
  command->add_flag("--largest-shell", *largest,
                    "Mesh only the largest closed shell of the surface (drops stray pieces)");
  auto repair = std::make_shared<std::string>("auto");
  auto repair_options = std::make_shared<SurfaceRepairOptions>();
  command
      ->add_option("--repair", *repair,
                   "What to do with a surface that is not closed and clean: auto (repair it in "
                   "place: duplicates, orientation, non-manifold vertices, borders, holes; wrap "
                   "it where that is not enough), in-place (never wrap), wrap (always "
                   "alpha-wrap), none (refuse it)")
      ->check(CLI::IsMember({"auto", "in-place", "wrap", "none"}))
      ->capture_default_str();
  command
      ->add_option("--wrap-alpha", repair_options->wrap_alpha,
                   "Alpha wrapping: gaps and cavities narrower than this are closed over "
                   "(surface units; 0: the bounding box diagonal / 100)")
      ->check(CLI::NonNegativeNumber);
  command
      ->add_option("--wrap-offset", repair_options->wrap_offset,
                   "Alpha wrapping: how far outside the input the wrap lies (surface units; 0: "
                   "the bounding box diagonal / 1000)")
      ->check(CLI::NonNegativeNumber);
  auto report_path = std::make_shared<std::string>();
  command->add_option("--report", *report_path,
                      "JSON report: what the repair changed, the distances, the mesh made");
  command->add_option("--timeout", options->timeout_seconds, "TetGen time limit (s)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  return [=]() {
    const auto start = Clock::now();
    SurfaceMesh surface = read_surface(*input);
    for (const std::string& note : surface.notes) {
      std::cerr << "note: " << note << "\n";
    }
    const std::vector<SurfaceMesh> shells = surface_shells(surface);
    std::cerr << fmt::format("surface: {} points, {} triangles, {} shell(s)\n",
                             surface.points.size(), surface.triangles.size(), shells.size());
    if (*largest && shells.size() > 1) {
      surface = shells.front();
      std::cerr << fmt::format("note: kept the largest shell ({} triangles), dropped {} others\n",
                               surface.triangles.size(), shells.size() - 1);
    }
    using RepairMode = SurfaceRepairOptions::Mode;
    repair_options->mode = *repair == "none"       ? RepairMode::kNone
                           : *repair == "in-place" ? RepairMode::kInPlace
                           : *repair == "wrap"     ? RepairMode::kWrap
                                                   : RepairMode::kAuto;
    SurfaceRepairReport repaired;
    surface = repair_surface(surface, *repair_options, repaired);
    for (const std::string& note : repaired.notes) {
      std::cerr << "repair: " << note << "\n";
    }
    options->remesh = *remesh == "always"  ? TetrahedralizeOptions::Remesh::kAlways
                      : *remesh == "never" ? TetrahedralizeOptions::Remesh::kNever
                                           : TetrahedralizeOptions::Remesh::kAuto;
    TetrahedralizeResult result = tetrahedralize(surface, *options);
    for (const std::string& note : result.notes) {
      std::cerr << "note: " << note << "\n";
    }
    const TetMesh& mesh = result.mesh;
    const ValidationReport report = validate(mesh);
    const QualitySummary quality = summarize_quality(mesh);
    write_tet_mesh(*output, mesh);
    const double seconds = seconds_since(start);
    std::cerr << fmt::format(
        "wrote {} ({} vertices, {} tetrahedra, volume {:.6g}, min dihedral {:.1f} deg, {:.2f} s)\n",
        *output, mesh.vertex_count(), mesh.tet_count(), total_volume(mesh),
        quality.min_dihedral_deg, seconds);
    if (!report_path->empty()) {
      nlohmann::ordered_json json;
      json["surface"] = *input;
      json["output"] = *output;
      json["repair"] = {{"changed", repaired.changed},
                        {"points_merged", repaired.points_merged},
                        {"triangles_removed", repaired.triangles_removed},
                        {"vertices_split", repaired.vertices_split},
                        {"edges_stitched", repaired.edges_stitched},
                        {"holes_filled", repaired.holes_filled},
                        {"hole_area", repaired.hole_area},
                        {"largest_hole_area", repaired.largest_hole_area},
                        {"reoriented", repaired.reoriented},
                        {"wrapped", repaired.wrapped},
                        {"alpha", repaired.alpha},
                        {"offset", repaired.offset},
                        {"result_to_input", repaired.result_to_input},
                        {"input_to_result", repaired.input_to_result},
                        {"notes", repaired.notes}};
      json["vertices"] = mesh.vertex_count();
      json["tets"] = mesh.tet_count();
      json["volume"] = total_volume(mesh);
      json["min_dihedral_deg"] = quality.min_dihedral_deg;
      json["valid"] = report.ok();
      json["seconds"] = seconds;
      write_file_atomically(*report_path, json.dump(2) + "\n");
    }
    if (!report.ok()) {
      std::cerr << "warning: the result does not validate:\n" << report.describe();
      return kExitError;
    }
    return 0;
  };
}

}  // namespace incise::app
