// incise cut MESH --blade PATH.csv --method xfem -o OUT.vtu [--visual SURFACE --visual-out
// OUT.vtp] [--report R.json]: the XFEM cut of a blade path, pose by pose as in the engine, no
// physics. OUT.vtu holds the virtual elements (copies of vertices appended after the
// originals) with their material fraction and rest tetrahedron as cell data.

#include "command_cut_xfem.hpp"

#include <fmt/format.h>

#include <iostream>

#include "commands.hpp"
#include "incise/batch/xfem_path_cut.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/blade.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::app {

int cut_xfem(const XfemCutRequest& request) {
  XfemPathCutRequest cut;
  cut.output = request.output;
  if (!request.visual.empty()) {
    cut.visual = read_surface(request.visual);
  }
  cut.visual_out = request.visual_out;
  cut.length_unit_m = request.length_unit_m;
  cut.mesh_name = request.mesh_path;
  cut.blade_name = request.blade_path;
  const XfemPathCutResult result = cut_xfem_along_path(read_tet_mesh(request.mesh_path).mesh,
                                                       read_blade_path(request.blade_path), cut);
  if (result.slivers_in > 0) {
    std::cerr << fmt::format("note: {} slivers (positive but tiny volume) in {}: cut as they are\n",
                             result.slivers_in, request.mesh_path);
  }
  std::cerr << result.summary << "\n";
  if (!request.report_path.empty()) {
    write_file_atomically(request.report_path, result.report_json);
  }
  return 0;
}

}  // namespace incise::app
