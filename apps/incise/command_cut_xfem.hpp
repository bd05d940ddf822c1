#pragma once
// The XFEM branch of incise cut.

#include <string>

namespace incise::app {

/// Cuts `mesh_path` along `blade_path` with XFEM virtual elements; writes `output` (.vtu) and
/// the report. Returns the exit code.
int cut_xfem(const std::string& mesh_path, const std::string& blade_path, const std::string& output,
             const std::string& report_path);

}  // namespace incise::app
