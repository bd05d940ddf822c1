#pragma once
// What each XFEM virtual element really is, for readers that know nothing of virtual elements
// (ParaView, meshio, a user's own integration). A virtual element is integrated over its whole
// rest tetrahedron, weighted by its material fraction; written as it is, the two elements of a
// split tetrahedron overlap and a volume integral counts the tetrahedron twice. Here each is
// clipped to its own side of the cut (the polygon through the edge crossings, quads as two
// triangles, as the physics integrates it) and cut into tetrahedra: the pieces fill exactly
// the side's part, so their volumes sum to the element's exact share, and the two lips part.
// Pure functions of rest positions, the cut and current positions: no model.

#include <array>
#include <span>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/xfem/element_cut.hpp"

namespace incise {

class TetMesh;
class XfemCutter;

/// The part of a tetrahedron (rest corners, m) on one side of its cut, as tetrahedra (m),
/// each positively oriented; their volumes sum to side_volumes() of that side. A cut that
/// does not split gives the whole tetrahedron to the side holding its corners, nothing to the
/// other.
[[nodiscard]] std::vector<std::array<Vec3, 4>> side_tetrahedra(const std::array<Vec3, 4>& corners,
                                                               const ElementCut& cut, bool side_b);

/// The body as tetrahedra that do not overlap: whole elements as they are, virtual elements
/// clipped to their sides. Points at current positions (m).
struct ClippedElements {
  std::vector<Vec3> points;      ///< the mesh's vertices (at `positions`), then clip points
  std::vector<Tet> tets;         ///< positively oriented at rest
  std::vector<TetId> element;    ///< per tetrahedron: the mesh element it is part of
  std::vector<double> fraction;  ///< per tetrahedron: that element's material fraction
};

/// Clips every virtual element of `mesh` (cut by `cutter`) to its side; points move with the
/// element that carries them (its barycentric map applied to `positions`, one per mesh vertex;
/// empty: the rest positions).
[[nodiscard]] ClippedElements clip_virtual_elements(const TetMesh& mesh, const XfemCutter& cutter,
                                                    std::span<const Vec3> positions = {});

}  // namespace incise
