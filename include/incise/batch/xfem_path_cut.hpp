#pragma once
// The XFEM cut of a whole blade path without physics, pose by pose as in the engine, written
// to files: what `incise cut --method xfem` does (and the Python module's incise.cut).

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "incise/cut/blade.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise {

/// What `incise cut --method xfem` was asked for beyond the mesh and the blade path.
struct XfemPathCutRequest {
  std::filesystem::path output;  ///< .vtu of the virtual elements (and OUTPUT_clipped.vtu beside)
  std::optional<SurfaceMesh> visual;    ///< a surface embedded in the mesh and cut with it
  std::filesystem::path visual_out;     ///< .vtp of the cut visual surface (empty: not written)
  std::optional<double> length_unit_m;  ///< m per mesh unit, when the user says it
  std::string mesh_name;                ///< names the mesh in the report and messages
  std::string blade_name;               ///< names the blade path in the report
};

/// What the XFEM cut along a path made.
struct XfemPathCutResult {
  std::string report_json;        ///< the keys `incise cut --method xfem --report` writes
  std::string summary;            ///< one line: elements, copies, DOFs, pieces, times
  std::size_t slivers_in = 0;     ///< slivers in the input mesh
  std::filesystem::path clipped;  ///< the clipped elements' .vtu
};

/// Cuts `mesh` along `path` with the XFEM cutter (virtual elements) and writes the request's
/// files. Throws InputError for an unusable mesh, an empty path or outputs of the wrong kind.
[[nodiscard]] XfemPathCutResult cut_xfem_along_path(TetMesh mesh,
                                                    const std::vector<BladePose>& path,
                                                    const XfemPathCutRequest& request);

}  // namespace incise
