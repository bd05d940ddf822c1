// incise info MESH [--json]: counts, extent, volume, quality and the validation report.

#include <fmt/format.h>

#include <algorithm>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/summary.hpp"
#include "incise/mesh/validate.hpp"

namespace incise::app {

Runner add_info_command(CLI::App& app) {
  auto* command = app.add_subcommand("info", "Describe and validate a tetrahedral mesh");
  auto path = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  command->add_option("mesh", *path, "Mesh file (.msh, .node/.ele, .mesh, .vtk, .vtu)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_flag("--json", *as_json, "Print one JSON object instead of text");
  auto labels = std::make_shared<std::string>();
  command->add_option("--labels", *labels,
                      "VTK cell array to take as region labels (default: the first integer one)");
  return [path, as_json, labels]() {
    const TetMeshReadResult read = read_tet_mesh(*path, ReadOptions{*labels});
    const TetMesh& mesh = read.mesh;
    // A frame (deformed points with their "displacement"): the mesh is judged in its rest
    // shape, and elements inside out in the positions the file holds are the state's, said
    // apart (a simulation's inversion, not a broken mesh).
    const bool frame = !read.rest_positions.empty();
    const ValidationReport report =
        frame ? validate(TetMesh(read.rest_positions,
                                 std::vector<Tet>(mesh.tets().begin(), mesh.tets().end())))
              : validate(mesh);
    const std::vector<TetId> inverted_in_positions =
        frame ? inverted_at(mesh, mesh.rest_positions()) : std::vector<TetId>{};
    const MeshSummary summary = summarize(mesh);
    const QualitySummary& quality = summary.quality;
    const auto& [low, high] = summary.bounds;
    // Slivers (positive but tiny volume) are listed, but a mesh with them is valid to use.
    const bool valid = report.usable();

    if (*as_json) {
      nlohmann::ordered_json out;
      out["file"] = *path;
      out["format"] = format_name(read.format);
      out["vertices"] = mesh.vertex_count();
      out["tets"] = mesh.tet_count();
      out["edges"] = mesh.edge_count();
      out["volume"] = summary.volume;
      out["virtual_elements"] = summary.virtual_elements;
      out["min_tet_volume"] = summary.min_tet_volume;
      out["max_tet_volume"] = summary.max_tet_volume;
      out["bounding_box"] = {{"min", {low.x(), low.y(), low.z()}},
                             {"max", {high.x(), high.y(), high.z()}}};
      out["inverted"] = report.inverted_tets.size();
      out["degenerate"] = report.degenerate_tets.size();
      out["slivers"] = report.sliver_tets.size();
      out["nonmanifold_faces"] = report.nonmanifold_faces.size();
      out["overlapping_tets"] = report.overlapping_tets.size();
      out["duplicate_tets"] = report.duplicate_tets.size();
      out["nonfinite_vertices"] = report.nonfinite_vertices.size();
      out["dropped_vertices"] = read.dropped_vertices;
      out["components"] = summary.components;
      out["regions"] = nlohmann::ordered_json::array();
      for (const auto& [label, region] : summary.regions) {
        out["regions"].push_back(
            {{"label", label}, {"tets", region.tets}, {"volume", region.volume}});
      }
      out["boundary_triangles"] = summary.boundary_triangles;
      out["watertight"] = summary.watertight;
      out["quality"] = {{"min_dihedral_deg", quality.min_dihedral_deg},
                        {"mean_min_dihedral_deg", quality.mean_min_dihedral_deg},
                        {"max_aspect_ratio", quality.max_aspect_ratio},
                        {"mean_aspect_ratio", quality.mean_aspect_ratio},
                        {"min_dihedral_histogram_10deg", quality.min_dihedral_histogram}};
      out["inverted_ids"] = report.inverted_tets;
      out["degenerate_ids"] = report.degenerate_tets;
      out["sliver_ids"] = report.sliver_tets;
      out["notes"] = read.notes;
      out["valid"] = valid;  // as a mesh: in its rest shape, for a frame
      out["rest_shape"] = frame ? "points minus 'displacement'" : "the points";
      if (frame) {
        out["inverted_in_positions"] = inverted_in_positions.size();
        out["inverted_in_positions_ids"] = inverted_in_positions;
      }
      std::cout << out.dump(2) << "\n";
      return valid ? 0 : kExitInvalid;
    }

    std::cout << fmt::format("{} ({})\n", *path, format_name(read.format));
    for (const std::string& note : read.notes) {
      std::cout << "  note: " << note << "\n";
    }
    std::cout << fmt::format("  vertices {}   tetrahedra {}   edges {}\n", mesh.vertex_count(),
                             mesh.tet_count(), mesh.edge_count());
    std::cout << fmt::format("  bounding box [{:.6g}, {:.6g}, {:.6g}] - [{:.6g}, {:.6g}, {:.6g}]\n",
                             low.x(), low.y(), low.z(), high.x(), high.y(), high.z());
    std::cout << fmt::format("  volume {:.9g}   tet volume min {:.4g} max {:.4g}\n", summary.volume,
                             summary.min_tet_volume, summary.max_tet_volume);
    std::cout << fmt::format("  components {}   boundary triangles {}   watertight {}\n",
                             summary.components, summary.boundary_triangles,
                             summary.watertight ? "yes" : "no");
    if (summary.regions.size() > 1 || summary.regions.begin()->first != 0) {
      std::cout << "  regions:";
      for (const auto& [label, region] : summary.regions) {
        std::cout << fmt::format("  {}: {} tets, volume {:.6g}", label, region.tets, region.volume);
      }
      std::cout << "\n";
    }
    std::cout << fmt::format(
        "  quality: min dihedral {:.2f} deg (mean of minima {:.2f}), aspect ratio max {:.3g} mean "
        "{:.3g}\n",
        quality.min_dihedral_deg, quality.mean_min_dihedral_deg, quality.max_aspect_ratio,
        quality.mean_aspect_ratio);
    std::cout << "  min dihedral angle histogram:\n";
    const std::size_t peak =
        std::max<std::size_t>(1, *std::max_element(quality.min_dihedral_histogram.begin(),
                                                   quality.min_dihedral_histogram.end()));
    for (std::size_t bin = 0; bin < quality.min_dihedral_histogram.size(); ++bin) {
      const std::size_t count = quality.min_dihedral_histogram[bin];
      const std::string label = bin + 1 < quality.min_dihedral_histogram.size()
                                    ? fmt::format("{:2}-{:2} deg", bin * 10, bin * 10 + 10)
                                    : fmt::format("  >={:2} deg", bin * 10);
      std::cout << fmt::format("    {} {:>8} {}\n", label, count,
                               std::string(40 * count / peak, '#'));
    }
    if (frame) {
      std::cout << fmt::format(
          "  a deformed frame: the mesh is judged in its rest shape (points minus "
          "'displacement'); in the positions it holds, {} tetrahedra are inside out{}\n",
          inverted_in_positions.size(),
          inverted_in_positions.empty() ? "" : " (the simulation's state, not the mesh)");
    }
    if (valid) {
      std::cout << (report.sliver_tets.empty()
                        ? std::string("  valid: yes\n")
                        : fmt::format("  valid: yes, with {} slivers (positive but tiny volume: "
                                      "cut and simulated as they are)\n",
                                      report.sliver_tets.size()));
    } else {
      std::cout << "  valid: NO\n";
      std::istringstream lines(report.describe());
      for (std::string line; std::getline(lines, line);) {
        std::cout << "    " << line << "\n";
      }
    }
    return valid ? 0 : kExitInvalid;
  };
}

}  // namespace incise::app
