#pragma once
// The XFEM body as a mesh of virtual elements (Molino et al. 2004's virtual nodes, equivalent
// to the seed's shifted-Heaviside enrichment): every tetrahedron the cut crosses completely is
// integrated twice over its unchanged rest shape, once per side, each weighted by its exact
// volume fraction; corners on the far side of each virtual element are copies of the real
// vertices. A vertex has one copy, shared by every split tetrahedron around it, so the
// elements on one side of a long cut share no node with those on the other and the pieces
// move independently. At the cut's front (a crossed edge that a tetrahedron not yet split
// also holds) the copies are tied to their originals (the seed's 3.5): the unfinished cut
// stays closed there. No rest element is ever created.

#include <optional>
#include <span>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"
#include "incise/xfem/element_cut.hpp"

namespace incise {

/// A cut mesh as XFEM sees it: the uncut tetrahedra and, for each split one, two virtual
/// elements over its whole rest shape, each with its share of the material.
struct VirtualMesh {
  /// Rest positions (m) of every node: the mesh's vertices, then the copies (each at its
  /// original's rest position).
  std::vector<Vec3> rest_positions;
  std::vector<VertexId> original_of;  ///< per node: the mesh vertex it is (or copies)
  std::vector<Tet> elements;          ///< uncut tetrahedra and virtual elements
  std::vector<TetId> rest_tet;        ///< per element: the rest tetrahedron it integrates over
  std::vector<double> fraction;       ///< per element: its share of that tetrahedron's volume
  std::size_t split = 0;              ///< tetrahedra split into two virtual elements
  std::size_t tied = 0;               ///< vertices of split tetrahedra tied at the cut's front
  std::size_t raised = 0;             ///< fractions raised to the minimum fraction

  /// Vertex copies the cut made.
  [[nodiscard]] std::size_t copies() const { return rest_positions.size() - first_copy; }
  /// Degrees of freedom the cut added (3 per copy).
  [[nodiscard]] std::size_t dofs_added() const { return 3 * copies(); }
  std::size_t first_copy = 0;  ///< the first copy's node index (the mesh's vertex count)
};

/// The virtual mesh of `mesh` cut as `cuts` says (one entry per tetrahedron: the cut of those
/// the cut crosses completely, nothing for the others). `front` lists tetrahedra the cut
/// reaches without crossing them completely (they stay whole; their crossed edges tie).
/// Conditioning: a virtual element whose exact fraction is below `min_fraction` is given
/// `min_fraction`, taken from its partner (the tetrahedron's material is conserved exactly);
/// a nearly empty element would otherwise make the system nearly singular. 0: exact fractions.
[[nodiscard]] VirtualMesh build_virtual_mesh(const TetMesh& mesh,
                                             std::span<const std::optional<ElementCut>> cuts,
                                             std::span<const TetId> front = {},
                                             double min_fraction = 0.0);

/// What a swept surface (triangles, m, in the rest frame) does to each tetrahedron of `mesh`:
/// the cut of those it crosses completely, and the front (those it reaches without crossing).
/// Brute force over the tetrahedra with a bounding-box filter (no spatial index yet).
struct SurfaceCuts {
  std::vector<std::optional<ElementCut>> cuts;  ///< per tetrahedron: its cut, if crossed
  std::vector<TetId> front;                     ///< tetrahedra reached but not crossed completely
};
[[nodiscard]] SurfaceCuts cuts_by_surface(const TetMesh& mesh,
                                          std::span<const std::array<Vec3, 3>> triangles);

/// Pieces of material: elements joined through shared nodes (elements of zero fraction do not
/// join anything). Returns the piece of every element (-1 for empty ones); `count` gets the
/// number of pieces.
[[nodiscard]] std::vector<int> virtual_pieces(const VirtualMesh& body, int* count = nullptr);

/// The material volume (m^3): every element's fraction of its rest tetrahedron's volume.
[[nodiscard]] double material_volume(const VirtualMesh& body, const TetMesh& mesh);

}  // namespace incise
