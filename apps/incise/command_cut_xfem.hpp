#pragma once
// The XFEM branch of incise cut.

#include <optional>
#include <string>

namespace incise::app {

struct XfemCutRequest {
  std::string mesh_path;
  std::string blade_path;
  std::string output;                   ///< .vtu of the virtual elements
  std::string report_path;              ///< empty: no report
  std::string visual;                   ///< empty: no visual surface
  std::string visual_out;               ///< .vtp of the cut visual surface
  std::optional<double> length_unit_m;  ///< m per mesh unit, when the user says it
};

/// Cuts the mesh along the blade path pose by pose with the XFEM cutter (virtual elements);
/// writes the output, the cut visual surface and the report. Returns the exit code.
int cut_xfem(const XfemCutRequest& request);

}  // namespace incise::app
