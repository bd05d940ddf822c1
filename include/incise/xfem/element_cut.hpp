#pragma once
// XFEM element maths (Gutierrez & Ramos, sections 3.1 and A; Molino et al. 2004): a
// tetrahedron the cut crosses completely becomes two virtual elements over the same rest
// tetrahedron, each weighted by the exact fraction of the tetrahedron's volume on its side.
// Pure functions of rest positions and the cut: no mesh, no model.
//
// The cut inside one tetrahedron is the surface through its edge crossings (the seed builds
// the cut surface from "the edge intersection points"): a triangle when one corner is alone on
// its side, two triangles over a quadrilateral when the corners split two and two. The side
// volumes are integrated exactly over that piecewise-planar surface (divergence theorem), so
// the two fractions sum to one to rounding, whatever the crossings.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "incise/core/types.hpp"

namespace incise {

/// How a cut crosses one tetrahedron: the corners on the far side b, and where each edge that
/// joins the two sides is crossed (fraction along tet_local::kEdges[k], from its first corner).
struct ElementCut {
  std::array<bool, 4> on_b{};        ///< per corner: on side b
  std::array<double, 6> crossing{};  ///< in (0, 1); read only for edges joining the sides
  /// Whether the cut separates the corners at all (some on each side).
  [[nodiscard]] bool splits() const;
};

/// Where the cut crosses the edge between corners i and j (either order; m).
[[nodiscard]] Vec3 crossing_point(const std::array<Vec3, 4>& corners, const ElementCut& cut, int i,
                                  int j);

/// Volumes (m^3) of a tetrahedron on each side of its cut.
struct SideVolumes {
  double a = 0.0;                                                  ///< m^3 on side a
  double b = 0.0;                                                  ///< m^3 on side b
  [[nodiscard]] double fraction_a() const { return a / (a + b); }  ///< side a's share
  [[nodiscard]] double fraction_b() const { return b / (a + b); }  ///< side b's share
};

/// The cut surface inside the tetrahedron: 3 or 4 crossing points (m) in cyclic order, their
/// fan (from the first point) oriented from side a towards side b. Empty when nothing splits.
[[nodiscard]] std::vector<Vec3> cut_polygon(const std::array<Vec3, 4>& corners,
                                            const ElementCut& cut);
/// The same polygon as the local edges (tet_local::kEdges indices) its points lie on.
[[nodiscard]] std::vector<int> cut_polygon_edges(const std::array<Vec3, 4>& corners,
                                                 const ElementCut& cut);

/// Exact volumes on each side of the cut surface (the tetrahedron must be positive).
[[nodiscard]] SideVolumes side_volumes(const std::array<Vec3, 4>& corners, const ElementCut& cut);

/// The cut of a tetrahedron by the plane through `point` with normal `normal`: corners with
/// (x - point) . normal > 0 lie on side b. Nothing when the plane leaves every corner on one
/// side (corners on the plane count as side a).
[[nodiscard]] std::optional<ElementCut> cut_by_plane(const std::array<Vec3, 4>& corners,
                                                     const Vec3& point, const Vec3& normal);

/// The cut a swept surface (triangles, m: the blade's sweep) makes in a tetrahedron, once it
/// crosses it completely: every edge the surface crosses (exact predicate) and the crossed
/// edges exactly those between one corner and three, or two and two. Side b is the one the
/// surface's normal points to (the vote of the crossed edges). Nothing while the surface has
/// crossed only part of the tetrahedron (semi-progressive: the physics waits) or none of it;
/// `crossed` (if given) gets the bit mask of crossed edges either way, in tet_local::kEdges
/// order, so a caller can tell a tetrahedron the cut has reached (the front).
[[nodiscard]] std::optional<ElementCut> cut_by_surface(
    const std::array<Vec3, 4>& corners, std::span<const std::array<Vec3, 3>> triangles,
    std::uint8_t* crossed = nullptr);

/// The two virtual elements of a split tetrahedron (virtual-node form of the shifted Heaviside
/// enrichment): element a keeps the real corners on side a and uses the copies of the others,
/// element b the reverse. `copies[k]` is the copy of corner k (shared with neighbours on the
/// same side, so a long cut separates the body).
struct VirtualElements {
  Tet a;  ///< the element holding side a
  Tet b;  ///< the element holding side b
};
[[nodiscard]] VirtualElements virtual_elements(const Tet& real, const ElementCut& cut,
                                               const Tet& copies);

}  // namespace incise
