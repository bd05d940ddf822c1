#pragma once
// What a mesh is, in numbers: what `incise info` prints and the Python module's Mesh.info()
// returns.

#include <map>
#include <utility>

#include "incise/mesh/quality.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// One region label's share of a mesh.
struct RegionSummary {
  std::size_t tets = 0;  ///< tetrahedra with the label
  double volume = 0.0;   ///< the material's (mesh units cubed)
};

/// What `incise info` reports of a mesh (mesh_summary()).
struct MeshSummary {
  /// The material's volume: XFEM virtual elements count by their fraction (the two elements of
  /// a split tetrahedron hold it once between them).
  double volume = 0.0;
  std::size_t virtual_elements = 0;      ///< elements with a material fraction below 1
  double min_tet_volume = 0.0;           ///< signed, of the geometric tetrahedra
  double max_tet_volume = 0.0;           ///< signed, of the geometric tetrahedra
  std::map<int, RegionSummary> regions;  ///< by region label
  std::pair<Vec3, Vec3> bounds;          ///< [low, high] of the rest positions
  int components = 0;                    ///< pieces connected through faces
  std::size_t boundary_triangles = 0;    ///< faces on one tetrahedron only
  bool watertight = false;  ///< every boundary edge shared by two boundary faces, consistently
  QualitySummary quality;   ///< dihedral angles and aspect ratios
};

[[nodiscard]] MeshSummary summarize(const TetMesh& mesh);

}  // namespace incise
