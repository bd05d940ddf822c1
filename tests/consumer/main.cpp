// Builds a box grid through the installed incise package and checks it.
#include <cmath>
#include <cstdio>
#include <incise/io/mesh_io.hpp>
#include <incise/mesh/generators.hpp>
#include <incise/mesh/validate.hpp>

int main() {
  incise::BoxGridOptions options;
  options.cells = {2, 3, 4};
  const incise::TetMesh mesh = incise::make_box_grid(options);
  const bool ok = mesh.tet_count() == 144 && incise::validate(mesh).ok() &&
                  std::abs(incise::total_volume(mesh) - 1.0) < 1e-12;
  std::printf("consumer: %zu tetrahedra, %s\n", mesh.tet_count(), ok ? "ok" : "WRONG");
  return ok ? 0 : 1;
}
