#pragma once
// Helpers shared by the tests: where the third-party test data lives, small meshes.

#include <cstdlib>
#include <filesystem>
#include <string>

#include "incise/mesh/tet_mesh.hpp"

namespace incise::test {

/// ../shared/data beside the project root (override with INCISE_DATA_DIR).
inline std::filesystem::path data_dir() {
  if (const char* dir = std::getenv("INCISE_DATA_DIR")) {
    return dir;
  }
  return std::filesystem::path(INCISE_SOURCE_DIR) / ".." / "shared" / "data";
}

inline std::filesystem::path data_file(const std::string& relative) {
  return data_dir() / relative;
}

/// A scratch directory for one test, emptied first.
inline std::filesystem::path scratch_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("incise-test-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// The standard tetrahedron (0,0,0), e1, e2, e3 scaled by `size` (m); volume size^3 / 6.
inline TetMesh unit_tet(double size = 1.0) {
  return TetMesh({Vec3(0, 0, 0), Vec3(size, 0, 0), Vec3(0, size, 0), Vec3(0, 0, size)},
                 {Tet{0, 1, 2, 3}});
}

}  // namespace incise::test
