#pragma once
// Boundary surface, surface closedness and connected components of a tetrahedral mesh.

#include <span>
#include <vector>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// One boundary triangle, outward oriented, with the tetrahedron face it comes from.
struct BoundaryFace {
  Triangle vertices;       ///< outward
  TetId tet = kInvalidId;  ///< the tetrahedron whose face it is
  int local_face = -1;     ///< tet_local::kFaces index
};

/// Faces that no other tetrahedron shares, oriented outward.
[[nodiscard]] std::vector<BoundaryFace> boundary_faces(const TetMesh& mesh);

/// Per boundary face, whether another boundary face lies on the same three rest positions: a
/// cut's lips (its faces back to back, on duplicated vertices), told apart from the body's
/// own surface in the files Gmsh and MEDIT users read.
[[nodiscard]] std::vector<bool> lip_faces(const TetMesh& mesh, std::span<const BoundaryFace> faces);

/// Closedness of a triangle surface, judged by its edges.
struct SurfaceEdgeCheck {
  std::size_t open_edges = 0;            ///< used by one triangle
  std::size_t nonmanifold_edges = 0;     ///< used by three or more triangles
  std::size_t misoriented_edges = 0;     ///< used twice in the same direction
  std::size_t degenerate_triangles = 0;  ///< repeating a vertex id
  /// Closed, two-manifold along edges and consistently oriented.
  [[nodiscard]] bool watertight() const {
    return open_edges == 0 && nonmanifold_edges == 0 && misoriented_edges == 0 &&
           degenerate_triangles == 0;
  }
};

[[nodiscard]] SurfaceEdgeCheck check_surface_edges(std::span<const Triangle> triangles);
[[nodiscard]] SurfaceEdgeCheck check_boundary(const TetMesh& mesh);

/// Whether the triangles close up: every edge is used as often in one direction as in the
/// other (once each on a smooth surface; along a partial cut's front, where the two lips meet,
/// or where two pieces touch along an edge, more than once each).
[[nodiscard]] bool is_watertight(std::span<const Triangle> triangles);
/// Volume (m^3) a closed, outward-oriented triangle surface encloses (divergence theorem);
/// negative when it faces in.
[[nodiscard]] double enclosed_volume(std::span<const Vec3> points,
                                     std::span<const Triangle> triangles);

/// Tetrahedra connected through shared faces. Returns one component id per tet (0-based,
/// numbered in order of first appearance) and sets `count`.
[[nodiscard]] std::vector<int> tet_components(const TetMesh& mesh, int* count = nullptr);

/// Pieces that share no vertex (tetrahedra joined through any shared corner): a cut has
/// separated two parts only when they are apart in this sense too, not only face by face.
[[nodiscard]] int pieces_by_vertices(const TetMesh& mesh);

/// Whether an edit added no open, non-manifold or misoriented boundary edge and no degenerate
/// boundary triangle, counted against the surface before it (an input mesh need not be
/// watertight: meshes from real pipelines have tetrahedra meeting only at an edge or vertex).
[[nodiscard]] bool cut_kept_boundary(const SurfaceEdgeCheck& before, const SurfaceEdgeCheck& after);

}  // namespace incise
