#pragma once
// The points some tetrahedron uses: reading drops the others, every writer leaves them out,
// and a repair that collapses vertices drops what it left behind.

#include <cstddef>
#include <span>
#include <vector>

#include "incise/core/types.hpp"

namespace incise {

/// The points some tetrahedron uses, numbered afresh in order (kInvalidId for the rest: a
/// cut's leftovers, which carry no mass and would stretch every point array's range), and how
/// many there are.
struct UsedPoints {
  std::vector<VertexId> index;  ///< per point: its new number, or kInvalidId
  std::size_t count = 0;        ///< points used
};
[[nodiscard]] UsedPoints used_points(std::span<const Tet> tets, std::size_t point_count);

/// Drops the points no tetrahedron uses and renumbers the tetrahedra; returns each old point's
/// new number (kInvalidId for those dropped).
std::vector<VertexId> drop_unused_points(std::vector<Vec3>& points, std::vector<Tet>& tets);

}  // namespace incise
