// incise generate box --cells NX NY NZ --size X Y Z --tets-per-cell 5|6 -o OUT

#include <fmt/format.h>

#include <iostream>

#include "commands.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/generators.hpp"

namespace incise::app {

Runner add_generate_command(CLI::App& app) {
  auto* command = app.add_subcommand("generate", "Generate structured tetrahedral meshes");
  command->require_subcommand(1);
  auto* box = command->add_subcommand("box", "A box split into 5 or 6 tetrahedra per cell");
  auto cells = std::make_shared<std::vector<int>>(std::vector<int>{4, 6, 4});
  auto size = std::make_shared<std::vector<double>>(std::vector<double>{0.04, 0.06, 0.04});
  auto origin = std::make_shared<std::vector<double>>(std::vector<double>{0.0, 0.0, 0.0});
  auto per_cell = std::make_shared<int>(6);
  auto output = std::make_shared<std::string>();
  box->add_option("--cells", *cells, "Cells along x, y, z")->expected(3)->capture_default_str();
  box->add_option("--size", *size, "Box edge lengths along x, y, z (m)")
      ->expected(3)
      ->capture_default_str();
  box->add_option("--origin", *origin, "Minimum corner (m)")->expected(3)->capture_default_str();
  box->add_option("--tets-per-cell", *per_cell, "5 or 6")
      ->check(CLI::IsMember({5, 6}))
      ->capture_default_str();
  box->add_option("-o,--output", *output, "Output mesh (.msh, .vtu, .mesh, .obj, .node)")
      ->required();
  return [=]() {
    BoxGridOptions options;
    options.cells = {(*cells)[0], (*cells)[1], (*cells)[2]};
    options.size = Vec3((*size)[0], (*size)[1], (*size)[2]);
    options.origin = Vec3((*origin)[0], (*origin)[1], (*origin)[2]);
    options.tets_per_cell = *per_cell;
    const TetMesh mesh = make_box_grid(options);
    write_tet_mesh(*output, mesh, 1.0);  // metres, as the options say
    std::cerr << fmt::format("wrote {} ({} vertices, {} tetrahedra, volume {:.6g} m^3)\n", *output,
                             mesh.vertex_count(), mesh.tet_count(), total_volume(mesh));
    return 0;
  };
}

}  // namespace incise::app
