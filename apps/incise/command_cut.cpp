// incise cut MESH --blade PATH.csv [--method subdivision|xfem] -o OUT [--report R.json]
//   [--visual SURFACE --visual-out OUT.vtp] (xfem) [--unit m|cm|mm]

#include <fmt/format.h>

#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command_cut_xfem.hpp"
#include "commands.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
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
    const ValidationReport input_report = validate(mesh);
    if (!input_report.usable()) {
      throw InputError(*mesh_path, 0, "the mesh is not valid:\n" + input_report.describe());
    }
    // Slivers of positive volume are cut like any tetrahedron (the predicates are exact); a
    // mesh that has none must keep none, one that has some may have their children.
    const bool slivers_in = !input_report.sliver_tets.empty();
    if (slivers_in) {
      std::cerr << fmt::format(
          "note: {} slivers (positive but tiny volume) in {}: cut as they are\n",
          input_report.sliver_tets.size(), *mesh_path);
    }
    const auto sound = [slivers_in](const ValidationReport& r) {
      return slivers_in ? r.usable() : r.ok();
    };
    const std::vector<BladePose> path = read_blade_path(*blade_path);
    const std::size_t tets_in = mesh.tet_count();
    const std::size_t vertices_in = mesh.vertex_count();
    const double volume_in = total_volume(mesh);
    const SurfaceEdgeCheck boundary_in = check_boundary(mesh);
    CutterOptions options;
    options.snap_fraction = *snap;
    options.split = *split == "generic" ? SplitMode::kGeneric : SplitMode::kMinimal;
    options.merge_blade_points = *merge;
    SubdivisionCutter cutter(mesh, options);
    std::size_t invalid_frames = 0;
    std::string first_problem;
    cutter.start(path.front());
    for (std::size_t i = 1; i < path.size(); ++i) {
      cutter.move_to(path[i]);
      const ValidationReport frame = validate(mesh);
      const SurfaceEdgeCheck boundary = check_boundary(mesh);
      if (!sound(frame) || !cut_kept_boundary(boundary_in, boundary)) {
        if (invalid_frames++ == 0) {
          first_problem = fmt::format(
              "after pose {}: {}", i,
              sound(frame) ? fmt::format("the cut added boundary edges that are open ({} -> {}), "
                                         "non-manifold ({} -> {}) or misoriented ({} -> {})",
                                         boundary_in.open_edges, boundary.open_edges,
                                         boundary_in.nonmanifold_edges, boundary.nonmanifold_edges,
                                         boundary_in.misoriented_edges, boundary.misoriented_edges)
                           : frame.describe());
        }
      }
    }
    const ValidationReport report = validate(mesh);
    const bool watertight = check_boundary(mesh).watertight();
    int components = 0;
    (void)tet_components(mesh, &components);
    const int vertex_pieces = pieces_by_vertices(mesh);
    const CutStats& stats = cutter.stats();
    write_tet_mesh(*output, mesh, length_unit_m);
    std::cerr << fmt::format(
        "cut {} with {} poses: {} -> {} tets, {} -> {} vertices, {} pieces ({} by vertices), cut "
        "area {:.4g} ({})^2, cd {:.3f} ms, gc {:.3f} ms in total, {:.3f} ms for the slowest "
        "pose\n",
        *mesh_path, path.size(), tets_in, mesh.tet_count(), vertices_in, mesh.vertex_count(),
        components, vertex_pieces, stats.cut_area, unit_name, 1e3 * stats.total_cd_seconds,
        1e3 * stats.total_gc_seconds, 1e3 * stats.max_move_seconds);
    if (!report_path->empty()) {
      nlohmann::ordered_json json;
      json["mesh"] = *mesh_path;
      json["blade"] = *blade_path;
      json["method"] = *method;
      json["length_unit"] = unit_name;  // of every length, area and volume below
      json["poses"] = path.size();
      json["tets_in"] = tets_in;
      json["tets_out"] = mesh.tet_count();
      json["vertices_in"] = vertices_in;
      json["vertices_out"] = mesh.vertex_count();
      json["volume_in"] = volume_in;
      json["volume_out"] = total_volume(mesh);
      json["components"] = components;
      json["pieces_by_vertices"] = vertex_pieces;
      json["watertight"] = watertight;
      json["watertight_in"] = boundary_in.watertight();
      json["inverted_tets"] = report.inverted_tets.size();
      json["valid"] = sound(report);
      json["slivers_in"] = input_report.sliver_tets.size();
      json["slivers_out"] = report.sliver_tets.size();
      json["invalid_frames"] = invalid_frames;
      json["min_volume_ratio"] = stats.min_volume_ratio;  // child / immediate parent
      json["cut_area"] = stats.cut_area;
      json["split"] = *split;
      json["blade_vertices"] = stats.blade_vertices;
      json["blade_slides"] = stats.blade_slides;
      json["blade_points_collapsed"] = stats.blade_points_collapsed;
      json["blade_points_left_out"] = stats.blade_points_left_out;
      json["swept_area"] = stats.swept_area;
      json["edges_split"] = stats.edges_split;
      json["vertices_duplicated"] = stats.vertices_duplicated;
      json["cut_faces"] = stats.cut_faces;
      json["cd"] = 1e3 * stats.total_cd_seconds;
      json["gc"] = 1e3 * stats.total_gc_seconds;
      json["max_pose_ms"] = 1e3 * stats.max_move_seconds;  // cd + gc of the slowest pose
      json["shards_kept"] = stats.shards_kept;
      nlohmann::ordered_json cases;
      for (CutCase kind :
           {CutCase::kA, CutCase::kB, CutCase::kC, CutCase::kD, CutCase::kE, CutCase::kInvalid}) {
        cases[cut_case_name(kind)] = stats.case_counts[static_cast<std::size_t>(kind)];
      }
      json["cut_cases"] = cases;
      // Per original tetrahedron, its cut-edge code accumulated over the whole path.
      const auto accumulated = cutter.accumulated_case_counts();
      nlohmann::ordered_json accumulated_cases;
      for (CutCase kind :
           {CutCase::kA, CutCase::kB, CutCase::kC, CutCase::kD, CutCase::kE, CutCase::kInvalid}) {
        accumulated_cases[cut_case_name(kind)] = accumulated[static_cast<std::size_t>(kind)];
      }
      json["accumulated_cut_cases"] = accumulated_cases;
      json["min_volume_ratio_to_original"] = cutter.min_volume_ratio_to_original();
      json["point_tet_hits"] = {{"same", stats.point_same},
                                {"neighbor", stats.point_neighbor},
                                {"global", stats.point_global},
                                {"outside", stats.point_outside}};
      write_file_atomically(*report_path, json.dump(2) + "\n");
    }
    if (invalid_frames > 0) {
      std::cerr << "error: the cut left an invalid mesh " << first_problem << "\n";
      return kExitError;
    }
    return 0;
  };
}

}  // namespace incise::app
