#include "incise/cut/path_cut.hpp"

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {

PathCutResult cut_along_path(TetMesh& mesh, const std::vector<BladePose>& path,
                             const CutterOptions& options, const std::string& mesh_name,
                             const std::string& blade_name, const std::string& unit_name) {
  if (path.empty()) {
    throw InputError(blade_name, 0, "the blade path has no pose");
  }
  PathCutResult result;
  const ValidationReport input_report = validate(mesh);
  if (!input_report.usable()) {
    throw InputError(mesh_name, 0, "the mesh is not valid:\n" + input_report.describe());
  }
  // Slivers of positive volume are cut like any tetrahedron (the predicates are exact); a
  // mesh that has none must keep none, one that has some may have their children.
  const bool slivers_in = !input_report.sliver_tets.empty();
  result.slivers_in = input_report.sliver_tets.size();
  const auto sound = [slivers_in](const ValidationReport& r) {
    return slivers_in ? r.usable() : r.ok();
  };
  const std::size_t tets_in = mesh.tet_count();
  const std::size_t vertices_in = mesh.vertex_count();
  const double volume_in = total_volume(mesh);
  const SurfaceEdgeCheck boundary_in = check_boundary(mesh);
  SubdivisionCutter cutter(mesh, options);
  cutter.start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    cutter.move_to(path[i]);
    const ValidationReport frame = validate(mesh);
    const SurfaceEdgeCheck boundary = check_boundary(mesh);
    if (!sound(frame) || !cut_kept_boundary(boundary_in, boundary)) {
      if (result.invalid_poses++ == 0) {
        result.first_problem = fmt::format(
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
  result.summary = fmt::format(
      "cut {} with {} poses: {} -> {} tets, {} -> {} vertices, {} pieces ({} by vertices), cut "
      "area {:.4g} ({})^2, cd {:.3f} ms, gc {:.3f} ms in total, {:.3f} ms for the slowest "
      "pose",
      mesh_name, path.size(), tets_in, mesh.tet_count(), vertices_in, mesh.vertex_count(),
      components, vertex_pieces, stats.cut_area, unit_name, 1e3 * stats.total_cd_seconds,
      1e3 * stats.total_gc_seconds, 1e3 * stats.max_move_seconds);
  {
    nlohmann::ordered_json json;
    json["mesh"] = mesh_name;
    json["blade"] = blade_name;
    json["method"] = "subdivision";
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
    json["invalid_frames"] = result.invalid_poses;
    json["min_volume_ratio"] = stats.min_volume_ratio;  // child / immediate parent
    json["cut_area"] = stats.cut_area;
    json["split"] = options.split == SplitMode::kGeneric ? "generic" : "minimal";
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
    result.report_json = json.dump(2) + "\n";
  }
  return result;
}

}  // namespace incise
