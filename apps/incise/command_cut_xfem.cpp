// incise cut MESH --blade PATH.csv --method xfem -o OUT.vtu [--report R.json]: the XFEM cut of
// a blade path, no physics. OUT.vtu holds the virtual elements (copies of vertices appended
// after the originals) with their material fraction and rest tetrahedron as cell data.

#include "command_cut_xfem.hpp"

#include <fmt/format.h>

#include <chrono>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/blade.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/xfem/virtual_mesh.hpp"

namespace incise::app {

int cut_xfem(const std::string& mesh_path, const std::string& blade_path, const std::string& output,
             const std::string& report_path) {
  if (std::filesystem::path(output).extension() != ".vtu") {
    throw InputError("-o " + output +
                     ": the XFEM cut is written as .vtu (virtual elements "
                     "with their material fraction as cell data)");
  }
  const TetMesh mesh = read_tet_mesh(mesh_path).mesh;
  const ValidationReport input_report = validate(mesh);
  if (!input_report.ok()) {
    throw InputError(mesh_path, 0, "the mesh is not valid:\n" + input_report.describe());
  }
  const std::vector<BladePose> path = read_blade_path(blade_path);
  std::vector<std::array<Vec3, 3>> triangles;
  double travel = 0.0;  // m, of the blade's midpoint
  for (std::size_t i = 1; i < path.size(); ++i) {
    for (const auto& triangle : swept_triangles(path[i - 1], path[i])) {
      triangles.push_back(triangle);
    }
    travel +=
        (0.5 * (path[i].tip + path[i].base) - 0.5 * (path[i - 1].tip + path[i - 1].base)).norm();
  }
  const auto start = std::chrono::steady_clock::now();
  const SurfaceCuts cuts = cuts_by_surface(mesh, triangles);
  const auto found = std::chrono::steady_clock::now();
  // A stated minimum fraction keeps nearly empty elements from making the system singular.
  constexpr double kMinFraction = 1e-3;
  const VirtualMesh body = build_virtual_mesh(mesh, cuts.cuts, cuts.front, kMinFraction);
  const auto built = std::chrono::steady_clock::now();
  int pieces = 0;
  (void)virtual_pieces(body, &pieces);
  double min_fraction = 1.0;
  for (double fraction : body.fraction) {
    min_fraction = std::min(min_fraction, fraction);
  }

  const TetMesh virtual_mesh(body.rest_positions, body.elements);
  VtuFields fields;
  fields.cell_data.push_back({"fraction", 1, body.fraction});
  fields.cell_data.push_back(
      {"rest_tet", 1, std::vector<std::int32_t>(body.rest_tet.begin(), body.rest_tet.end())});
  write_vtu(output, virtual_mesh, {}, fields);

  const double cd = std::chrono::duration<double, std::milli>(found - start).count();
  const double gc = std::chrono::duration<double, std::milli>(built - found).count();
  const double volume_out = material_volume(body, mesh);
  std::cerr << fmt::format(
      "xfem cut {} with {} poses: {} tets, {} split into virtual elements ({} elements), {} "
      "copies ({} DOFs, {:.1f} per cm of blade travel), {} pieces, smallest fraction {:.3g}, "
      "cd {:.3f} ms, gc {:.3f} ms\n",
      mesh_path, path.size(), mesh.tet_count(), body.split, body.elements.size(), body.copies(),
      body.dofs_added(), travel > 0.0 ? body.dofs_added() / (100.0 * travel) : 0.0, pieces,
      min_fraction, cd, gc);
  if (!report_path.empty()) {
    const nlohmann::json json = {
        {"mesh", mesh_path},
        {"blade", blade_path},
        {"method", "xfem"},
        {"poses", path.size()},
        {"tets_in", mesh.tet_count()},
        {"tets_out", body.elements.size()},
        {"vertices_in", mesh.vertex_count()},
        {"vertices_out", body.rest_positions.size()},
        {"volume_in", total_volume(mesh)},
        {"volume_out", volume_out},
        {"components", pieces},
        {"inverted_tets", 0},  // no rest element is created or changed
        {"cd", cd},
        {"gc", gc},
        {"elements_split", body.split},
        {"front_tets", cuts.front.size()},
        {"tied_vertices", body.tied},
        {"dofs_added", body.dofs_added()},
        {"blade_travel_m", travel},
        {"dofs_added_per_cm", travel > 0.0 ? body.dofs_added() / (100.0 * travel) : 0.0},
        {"min_fraction", min_fraction},
        {"fractions_raised", body.raised}};
    write_file_atomically(report_path, json.dump(2) + "\n");
  }
  return 0;
}

}  // namespace incise::app
