// The XFEM cut of a blade path, pose by pose as in the engine, no physics. The output .vtu
// holds the virtual elements (copies of vertices appended after the originals) with their
// material fraction and rest tetrahedron as cell data; OUTPUT_clipped.vtu beside it holds them
// clipped to their sides.

#include "incise/batch/xfem_path_cut.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "incise/batch/visual_report.hpp"
#include "incise/core/error.hpp"
#include "incise/engine/frame_sink.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/xfem/clipped_elements.hpp"
#include "incise/xfem/visual_surface.hpp"
#include "incise/xfem/xfem_cutter.hpp"

namespace incise {

XfemPathCutResult cut_xfem_along_path(TetMesh mesh, const std::vector<BladePose>& path,
                                      const XfemPathCutRequest& request) {
  XfemPathCutResult result;
  if (request.output.extension() != ".vtu") {
    throw InputError("-o " + request.output.string() +
                     ": the XFEM cut is written as .vtu (virtual elements "
                     "with their material fraction as cell data)");
  }
  if (!request.visual_out.empty() && !request.visual) {
    throw InputError("--visual-out needs --visual SURFACE");
  }
  if (!request.visual_out.empty() && request.visual_out.extension() != ".vtp") {
    throw InputError("--visual-out " + request.visual_out.string() +
                     ": the visual surface is written as .vtp");
  }
  if (path.empty()) {
    throw InputError(request.blade_name, 0, "the blade path has no pose");
  }
  const ValidationReport input_report = validate(mesh);
  if (!input_report.usable()) {
    throw InputError(request.mesh_name, 0, "the mesh is not valid:\n" + input_report.describe());
  }
  result.slivers_in = input_report.sliver_tets.size();
  const std::size_t tets_in = mesh.tet_count();
  const std::size_t vertices_in = mesh.vertex_count();
  const double volume_in = total_volume(mesh);
  std::unique_ptr<VisualSurface> visual;
  double visual_volume_in = 0.0;
  if (request.visual) {
    visual_volume_in = enclosed_volume(request.visual->points, request.visual->triangles);
    visual =
        std::make_unique<VisualSurface>(mesh, request.visual->points, request.visual->triangles);
  }

  XfemCutter cutter(mesh);
  double travel = 0.0;  // mesh units, of the blade's midpoint
  double cd = 0.0;      // ms, over all poses
  double gc = 0.0;
  cutter.start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    cutter.move_to(path[i]);
    cd += 1e3 * cutter.stats().cd_seconds;
    gc += 1e3 * cutter.stats().gc_seconds;
    travel +=
        (0.5 * (path[i].tip + path[i].base) - 0.5 * (path[i - 1].tip + path[i - 1].base)).norm();
  }
  if (visual) {
    visual->follow(mesh, cutter);
  }
  const XfemCutterStats& stats = cutter.stats();
  std::vector<std::int32_t> rest_tet(mesh.tet_count());
  for (std::size_t t = 0; t < rest_tet.size(); ++t) {
    rest_tet[t] = cutter.rest_tet_of(static_cast<TetId>(t));
  }
  double volume_out = 0.0;  // m^3, fraction-weighted
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    volume_out +=
        mesh.material_fraction(static_cast<TetId>(t)) * signed_volume(mesh, static_cast<TetId>(t));
  }
  VtuFields fields;
  fields.cell_data.push_back(
      {"fraction", 1,
       std::vector<double>(mesh.material_fractions().begin(), mesh.material_fractions().end())});
  fields.cell_data.push_back({"rest_tet", 1, std::move(rest_tet)});
  fields.length_unit_m = request.length_unit_m;
  write_vtu(request.output, mesh, {}, fields);
  // Beside it, the virtual elements clipped to their sides: what ParaView integrates to the
  // true volume and shows as two lips.
  std::filesystem::path clipped_path = request.output;
  clipped_path.replace_filename(clipped_path.stem().string() + "_clipped.vtu");
  const ClippedElements clipped = clip_virtual_elements(mesh, cutter);
  write_clipped_vtu(clipped_path, clipped, std::nullopt, request.length_unit_m);
  double clipped_volume = 0.0;  // mesh units cubed: what a reader integrates from that file
  for (const Tet& t : clipped.tets) {
    clipped_volume += signed_volume(clipped.points[static_cast<std::size_t>(t[0])],
                                    clipped.points[static_cast<std::size_t>(t[1])],
                                    clipped.points[static_cast<std::size_t>(t[2])],
                                    clipped.points[static_cast<std::size_t>(t[3])]);
  }
  if (visual && !request.visual_out.empty()) {
    VtuFields surface_fields;
    surface_fields.length_unit_m = request.length_unit_m;
    surface_fields.cell_data.push_back(
        {"on_cut", 1, std::vector<std::int32_t>(visual->on_cut().begin(), visual->on_cut().end())});
    write_vtp(request.visual_out, visual->rest_points(), visual->triangles(), surface_fields);
  }

  const int pieces = pieces_by_vertices(mesh);
  // Blade travel is in the mesh's units: per centimetre only where the unit is known.
  const std::string unit = length_unit_name(request.length_unit_m);
  const double per_unit = travel > 0.0 ? static_cast<double>(cutter.dofs_added()) / travel : 0.0;
  const bool unit_known = request.length_unit_m.has_value();
  const double per_cm = unit_known ? per_unit * 1e-2 / request.length_unit_m.value() : 0.0;
  result.clipped = clipped_path;
  result.summary = fmt::format(
      "xfem cut {} with {} poses: {} tets, {} split into virtual elements ({} elements), {} "
      "copies ({} DOFs, {}), {} pieces, smallest fraction {:.3g}, cd {:.3f} ms, gc {:.3f} ms",
      request.mesh_name, path.size(), tets_in, stats.elements_split, mesh.tet_count(), stats.copies,
      cutter.dofs_added(),
      unit_known ? fmt::format("{:.1f} per cm of blade travel", per_cm)
                 : fmt::format("{:.3g} per {} of blade travel", per_unit, unit),
      pieces, stats.min_fraction, cd, gc);
  {
    nlohmann::json json = {{"mesh", request.mesh_name},
                           {"blade", request.blade_name},
                           {"method", "xfem"},
                           {"length_unit", unit},  // of every length, area and volume here
                           {"poses", path.size()},
                           {"tets_in", tets_in},
                           {"tets_out", mesh.tet_count()},
                           {"vertices_in", vertices_in},
                           {"vertices_out", mesh.vertex_count()},
                           {"volume_in", volume_in},
                           {"volume_out", volume_out},
                           {"components", pieces},
                           {"inverted_tets", validate(mesh).inverted_tets.size()},
                           {"cd", cd},
                           {"gc", gc},
                           {"elements_split", stats.elements_split},
                           {"front_tets", stats.front_tets},
                           {"waiting_tets", stats.waiting_tets},
                           {"tied_vertices", stats.tied_vertices},
                           {"tremor_edges", stats.tremor_edges},
                           {"dofs_added", cutter.dofs_added()},
                           {"blade_travel", travel},
                           {"dofs_added_per_length_unit", per_unit},
                           {"min_fraction", stats.min_fraction},
                           {"fractions_raised", stats.fractions_raised},
                           {"clipped", clipped_path.string()},
                           {"clipped_tets", clipped.tets.size()},
                           {"clipped_volume", clipped_volume}};
    if (unit_known) {
      json["dofs_added_per_cm"] = per_cm;
    }
    if (visual) {
      json["visual_volume_in"] = visual_volume_in;
      json["visual_volume_out"] = enclosed_volume(visual->rest_points(), visual->triangles());
      json["visual_watertight"] = is_watertight(visual->triangles());
      json["visual_triangles"] = visual->triangles().size();
      json["visual_outside_points"] = visual->outside_points();
      json["visual_failures"] = visual->failures();
      json["visual_surface"] = visual_surface_report(*visual);
    }
    result.report_json = json.dump(2) + "\n";
  }
  return result;
}

}  // namespace incise
