#pragma once
// Tetrahedralisation of a closed triangle surface with TetGen (Debian's libtet). A separate
// module (incise::meshing) because TetGen is AGPL-3: users who link only the other modules
// are not bound by it.

#include <string>
#include <vector>

#include "incise/io/mesh_io.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// How `incise mesh` fills a surface with tetrahedra (TetGen).
struct TetrahedralizeOptions {
  /// Largest tetrahedron volume, in the surface's units cubed; 0 leaves it to TetGen.
  double max_volume = 0.0;
  /// Bound on each tetrahedron's radius-edge ratio (TetGen -q); smaller is better, >= 1.1.
  double max_radius_edge_ratio = 1.5;
  /// Smallest dihedral angle TetGen aims for (degrees, TetGen -q.../angle); 0 for none.
  double min_dihedral_deg = 0.0;
  /// Keep the input triangles as they are (no Steiner points on the boundary). When false
  /// and TetGen cannot recover the boundary with added points, it is retried with this set.
  bool preserve_surface = false;
  /// Wall-clock limit for TetGen (s); it runs in a child process that is stopped after this.
  double timeout_seconds = 600.0;
  /// Remesh the surface (CGAL isotropic remeshing) before tetrahedralising. kAuto does so when
  /// the surface has needle triangles (an angle below `needle_angle_deg`), which would
  /// otherwise become flat boundary tetrahedra or stop TetGen.
  enum class Remesh { kAuto, kNever, kAlways };
  Remesh remesh = Remesh::kAuto;  ///< whether to remesh first
  double needle_angle_deg = 1.0;  ///< degrees: a smaller triangle angle is a needle
  /// Target edge length of the remeshed surface (surface units); 0: the median input edge.
  double remesh_edge_length = 0.0;
};

/// The tetrahedral mesh and how it was made.
struct TetrahedralizeResult {
  TetMesh mesh;                    ///< in the surface's units
  std::vector<std::string> notes;  ///< what was done to get there (remeshing, retries)
};

/// Smallest corner angle of any triangle (degrees).
[[nodiscard]] double min_triangle_angle_deg(const SurfaceMesh& surface);

/// Connected pieces of a surface, largest (by triangle count) first.
[[nodiscard]] std::vector<SurfaceMesh> surface_shells(const SurfaceMesh& surface);

/// Isotropic remeshing of a closed surface to a target edge length (CGAL), keeping it closed.
[[nodiscard]] SurfaceMesh remesh_surface(const SurfaceMesh& surface, double edge_length);

/// What keeps a surface from bounding a volume (check_surface).
struct SurfaceCheckReport {
  std::size_t open_edges = 0;            ///< edges on one triangle
  std::size_t nonmanifold_edges = 0;     ///< edges on more than two
  std::size_t misoriented_edges = 0;     ///< edges used twice the same way
  std::size_t degenerate_triangles = 0;  ///< of zero area
  /// Pairs of triangles that intersect (other than by shared vertices or edges); at most 10.
  std::vector<std::pair<std::size_t, std::size_t>> self_intersections;
  /// Whether nothing is wrong.
  [[nodiscard]] bool ok() const;
  /// What is wrong, in words: a line per kind, with the first self-intersecting pairs.
  [[nodiscard]] std::string describe() const;
};

/// Checks that a surface can bound a volume: closed, manifold, consistently oriented, with no
/// zero-area triangles and no self-intersections (exact predicates).
[[nodiscard]] SurfaceCheckReport check_closed_surface(const SurfaceMesh& surface);

/// Tetrahedralises the volume bounded by `surface`. Throws InputError naming the problem when
/// the surface is open, self-intersecting or otherwise unusable; never hangs on such input.
/// The result is positively oriented.
[[nodiscard]] TetrahedralizeResult tetrahedralize(const SurfaceMesh& surface,
                                                  const TetrahedralizeOptions& options = {});

}  // namespace incise
