#include "incise/xfem/clipped_elements.hpp"

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/xfem/xfem_cutter.hpp"

namespace incise {

std::vector<std::array<Vec3, 4>> side_tetrahedra(const std::array<Vec3, 4>& corners,
                                                 const ElementCut& cut, bool side_b) {
  const auto on_side = [&](int c) { return cut.on_b[static_cast<std::size_t>(c)] == side_b; };
  if (!cut.splits()) {
    if (on_side(0)) {
      return {corners};
    }
    return {};
  }
  // The side's region is closed by the side's parts of the four faces (outward) and the cut
  // surface (its fan oriented from a to b: outward for side a, reversed for b). Coned from a
  // corner on the side: faces through that corner add nothing, every other outward triangle
  // (p, q, r) adds the tetrahedron (apex, p, q, r).
  int apex = 0;
  while (!on_side(apex)) {
    ++apex;
  }
  const Vec3& top = corners[static_cast<std::size_t>(apex)];
  std::vector<std::array<Vec3, 4>> pieces;
  const auto add_fan = [&](const std::vector<Vec3>& polygon) {
    for (std::size_t m = 1; m + 1 < polygon.size(); ++m) {
      const std::array<Vec3, 4> piece{top, polygon[0], polygon[m], polygon[m + 1]};
      if (signed_volume(piece[0], piece[1], piece[2], piece[3]) != 0.0) {
        pieces.push_back(piece);
      }
    }
  };
  std::vector<Vec3> fan = cut_polygon(corners, cut);
  if (side_b) {
    std::reverse(fan.begin() + 1, fan.end());
  }
  add_fan(fan);
  // The one face without the apex: the face opposite it (counter-clockwise from outside).
  const auto& face = tet_local::kFaces[static_cast<std::size_t>(apex)];
  std::vector<Vec3> part;
  for (std::size_t m = 0; m < 3; ++m) {
    const int i = face[m];
    const int j = face[(m + 1) % 3];
    if (on_side(i)) {
      part.push_back(corners[static_cast<std::size_t>(i)]);
    }
    if (on_side(i) != on_side(j)) {
      part.push_back(crossing_point(corners, cut, i, j));
    }
  }
  if (part.size() >= 3) {
    add_fan(part);
  }
  return pieces;
}

ClippedElements clip_virtual_elements(const TetMesh& mesh, const XfemCutter& cutter,
                                      std::span<const Vec3> positions) {
  if (positions.empty()) {
    positions = mesh.rest_positions();
  }
  INCISE_ASSERT(positions.size() == mesh.vertex_count(), "one position per mesh vertex");
  ClippedElements out;
  out.points.assign(positions.begin(), positions.end());
  for (std::size_t e = 0; e < mesh.tet_count(); ++e) {
    const auto element = static_cast<TetId>(e);
    const TetId rest = cutter.rest_tet_of(element);
    const auto& cut = cutter.cut_of(rest);
    const Tet& nodes = mesh.tet(element);
    const double fraction = mesh.material_fraction(element);
    if (!cut) {
      out.tets.push_back(nodes);
      out.element.push_back(element);
      out.fraction.push_back(fraction);
      continue;
    }
    // Side b: the second element, or the only one when side a holds no material.
    const TetId second = cutter.second_element(rest);
    const bool side_b = second == kInvalidId || element == second;
    // The element's rest tetrahedron: its nodes' rest positions (copies sit at their
    // originals' places), the same corners in the same order as the rest tetrahedron's.
    std::array<Vec3, 4> corners{};
    std::array<Vec3, 4> now{};
    for (std::size_t k = 0; k < 4; ++k) {
      corners[k] = mesh.rest_position(nodes[k]);
      now[k] = positions[static_cast<std::size_t>(nodes[k])];
    }
    for (const auto& piece : side_tetrahedra(corners, *cut, side_b)) {
      Tet tet{};
      for (std::size_t k = 0; k < 4; ++k) {
        const auto w =
            barycentric_coordinates(piece[k], corners[0], corners[1], corners[2], corners[3]);
        tet[k] = static_cast<VertexId>(out.points.size());
        out.points.push_back(w[0] * now[0] + w[1] * now[1] + w[2] * now[2] + w[3] * now[3]);
      }
      out.tets.push_back(tet);
      out.element.push_back(element);
      out.fraction.push_back(fraction);
    }
  }
  return out;
}

}  // namespace incise
