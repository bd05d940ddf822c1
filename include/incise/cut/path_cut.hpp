#pragma once
// A mesh cut along a whole blade path without physics, every pose checked: what `incise cut`
// does (and the Python module's incise.cut), with the report both give.

#include <string>
#include <vector>

#include "incise/cut/subdivision_cutter.hpp"

namespace incise {

/// What cutting a mesh along a whole blade path gave (`incise cut`).
struct PathCutResult {
  /// The report as JSON text (the keys `incise cut --report` writes; lengths in the mesh's
  /// unit). `mesh`, `blade` and `length_unit` name what was cut.
  std::string report_json;
  std::size_t slivers_in = 0;     ///< positive-volume slivers in the input (cut as they are)
  std::size_t invalid_poses = 0;  ///< poses after which the mesh was not sound
  std::string first_problem;      ///< what went wrong after the first of them
  std::string summary;            ///< one line: counts, pieces, area, times
};

/// Cuts `mesh` (edited in place) with the subdivision cutter along `path`. Throws InputError
/// if the mesh is not usable (naming the problems) or the path has no pose. `mesh_name`,
/// `blade_name` and `unit_name` label the report.
[[nodiscard]] PathCutResult cut_along_path(TetMesh& mesh, const std::vector<BladePose>& path,
                                           const CutterOptions& options,
                                           const std::string& mesh_name,
                                           const std::string& blade_name,
                                           const std::string& unit_name);

}  // namespace incise
