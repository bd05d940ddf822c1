#pragma once
// Mesh validation: every problem is reported with the ids of the elements involved.

#include <array>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// How strict validate() is.
struct ValidationOptions {
  /// A tetrahedron of positive volume (exact orientation) whose normalised volume (volume over
  /// that of the regular tetrahedron with the same root-mean-square edge length, 1 when
  /// regular) is below this is a sliver; one of zero volume is degenerate.
  double degenerate_tolerance = 1e-6;
};

/// What validate() found, by kind of problem.
struct ValidationReport {
  std::vector<VertexId> nonfinite_vertices;  ///< NaN or Inf coordinates
  std::vector<TetId> inverted_tets;          ///< exactly negative orientation
  std::vector<TetId> degenerate_tets;        ///< exactly flat (zero volume)
  /// Positive volume, but tiny normalised volume: every mesher leaves some. The cutters'
  /// predicates are exact and the models give them their (small) mass and stiffness, so a
  /// mesh with slivers is usable(); ok() still counts them (a cut's own output must have none).
  std::vector<TetId> sliver_tets;
  std::vector<std::array<VertexId, 3>> nonmanifold_faces;  ///< shared by 3+ tetrahedra
  /// Interior faces whose two tetrahedra lie on the same side (they overlap).
  std::vector<std::pair<TetId, TetId>> overlapping_tets;
  std::vector<std::pair<TetId, TetId>> duplicate_tets;  ///< same vertex set
  std::vector<VertexId> unreferenced_vertices;          ///< used by no tetrahedron

  /// True when nothing is wrong. Unreferenced vertices are reported but tolerated.
  [[nodiscard]] bool ok() const;
  /// True when nothing but slivers (and unreferenced vertices) is wrong: a mesh to simulate
  /// and cut, with a warning.
  [[nodiscard]] bool usable() const;
  [[nodiscard]] std::size_t problem_count() const;  ///< problems of every kind, counted
  /// Human-readable list of problems, at most `max_listed` ids per kind.
  [[nodiscard]] std::string describe(std::size_t max_listed = 10) const;
};

[[nodiscard]] ValidationReport validate(const TetMesh& mesh, const ValidationOptions& options = {});

/// Tetrahedra turned inside out (signed volume zero or below) at `positions` (one per vertex):
/// the deformed state, where validate() looks at the rest shape.
[[nodiscard]] std::vector<TetId> inverted_at(const TetMesh& mesh, std::span<const Vec3> positions);

/// Normalised volume of a tetrahedron: 1 for the regular one, 0 when flat, negative inverted.
[[nodiscard]] double normalized_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

}  // namespace incise
