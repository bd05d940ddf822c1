#pragma once
// The visual surface of an XFEM body (Gutierrez & Ramos 3.2, 3.4): a triangle surface finer
// than the physics mesh, embedded barycentrically in its rest tetrahedra, that follows the
// cut. When tetrahedra split, the surface is cut along the cut surface the physics sees (in
// each split tetrahedron the polygon through its edge crossings, quads as two triangles): the
// visual triangles the cut crosses are split along it (CGAL's corefinement, exact predicates),
// the cut surface inside the visual volume is added once per side, and every point is embedded
// in the virtual element on its side. Points are shared wherever they would move together
// (same rest place, same nodes of the physics mesh), so each piece's surface is closed and a
// cut front still closed in the physics is closed in the picture too.
//
// A point outside the physics mesh (a visual surface that sticks out of it, as SOFA's
// liver-smooth.obj around liver.msh) is carried by its nearest tetrahedron, extrapolated.

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <unordered_map>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/cut/tet_grid.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

class XfemCutter;

/// A point carried by a tetrahedron of the physics mesh: x = sum weights[k] * x(nodes[k]).
struct Embedding {
  Tet nodes{};
  std::array<double, 4> weights{};
};

class VisualSurface {
 public:
  /// Embeds `points`/`triangles` (m, rest frame; outward, closed for a closed result) in the
  /// rest tetrahedra of `mesh`, which no cut has touched yet.
  VisualSurface(const TetMesh& mesh, std::vector<Vec3> points, std::vector<Triangle> triangles);
  ~VisualSurface();
  VisualSurface(const VisualSurface&) = delete;
  VisualSurface& operator=(const VisualSurface&) = delete;

  /// Follows the cut `cutter` has made in `mesh` so far (does nothing when no tetrahedron
  /// split since the last call). The surface is rebuilt from the original one, so it never
  /// accumulates error.
  void follow(const TetMesh& mesh, const XfemCutter& cutter);

  /// Current positions (m) of the surface's points, from the physics nodes' positions.
  [[nodiscard]] std::vector<Vec3> positions(std::span<const Vec3> nodes) const;
  [[nodiscard]] std::span<const Vec3> rest_points() const { return rest_points_; }
  [[nodiscard]] std::span<const Triangle> triangles() const { return triangles_; }
  /// Per triangle: 1 when it lies on the cut surface, 0 on the original surface.
  [[nodiscard]] std::span<const std::uint8_t> on_cut() const { return on_cut_; }
  [[nodiscard]] std::span<const Embedding> embeddings() const { return embedding_; }
  /// Points of the original surface outside the physics mesh.
  [[nodiscard]] std::size_t outside_points() const { return outside_; }
  /// Whether the original surface is closed (else no cut face is added: it has no inside).
  [[nodiscard]] bool original_closed() const { return closed_; }
  /// Updates CGAL's corefinement gave up on (a surface that intersects itself); the surface
  /// then kept its previous cut.
  [[nodiscard]] std::size_t failures() const { return failures_; }
  /// Updates whose pieces in front of the blade CGAL could not corefine: those were drawn
  /// without them (the cut the physics sees only).
  [[nodiscard]] std::size_t front_failures() const { return front_failures_; }
  /// Grows each time the surface's triangles change (a renderer uploads them again then).
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

 private:
  /// The rest tetrahedron holding p, or the nearest one (`outside` set) for a point outside.
  TetId locate(const Vec3& p, bool* outside = nullptr) const;
  /// p's embedding in the element on the side of the cut that p + a little of `towards` lies.
  Embedding embed(const TetMesh& mesh, const XfemCutter* cutter, const Vec3& p,
                  const Vec3& towards) const;

  TetId locate_uncached(const Vec3& p, bool& is_outside) const;
  /// Extends the cut surface past the body's boundary far enough to cut a visual surface that
  /// sticks out of the body: a band extruded outwards in each polygon's plane from the cut's
  /// rim on the boundary.
  void add_skirt(std::vector<Vec3>& points, std::vector<Triangle>& triangles,
                 std::span<const std::uint64_t> edge_of_point) const;
  /// The cut so far inside the tetrahedra the blade has reached but not crossed (`front`):
  /// polygons through their edges' crossings and the blade's line in them now.
  void add_front_pieces(const XfemCutter& cutter, std::span<const TetId> front,
                        std::unordered_map<std::uint64_t, VertexId>& crossing_point,
                        std::vector<Vec3>& points, std::vector<Triangle>& triangles,
                        std::vector<std::uint64_t>& edge_of_point) const;
  /// m: from p to the nearest point of the original surface.
  [[nodiscard]] double nearest_visual_distance(const Vec3& p) const;
  /// Drops triangles rounding made flat and welds the seam where the picture's cut runs past
  /// the physics' front.
  void tidy();

  /// The original surface as CGAL's mesh and its inside test, made once (every update starts
  /// from them).
  struct CgalCache;
  std::unique_ptr<CgalCache> cgal_;
  TetMesh rest_mesh_;  ///< the physics mesh before any cut (its tetrahedra are the rest ones)
  std::unique_ptr<TetGrid> grid_;
  double nudge_ = 0.0;  ///< m: how far past a point its side is read
  double reach_ = 0.0;  ///< m: how far the surface sticks out of the body at most
  mutable std::map<std::array<double, 3>, std::pair<TetId, bool>> located_;
  std::set<std::array<VertexId, 3>> rest_boundary_;  ///< sorted vertex ids of boundary faces
  double point_cell_ = 1.0;  ///< m: cell of the grid over the original points
  std::map<std::array<long, 3>, std::vector<std::size_t>> point_cells_;
  /// The cell of point_cells_ that holds q (saturated far out: see core/clamped_floor.hpp).
  [[nodiscard]] std::array<long, 3> point_cell_of(const Vec3& q) const;
  std::vector<Vec3> original_points_;
  std::vector<Triangle> original_triangles_;
  std::vector<Vec3> rest_points_;
  std::vector<Triangle> triangles_;
  std::vector<std::uint8_t> on_cut_;
  std::vector<Embedding> embedding_;
  std::size_t outside_ = 0;
  std::size_t split_seen_ = 0;
  std::size_t moves_seen_ = 0;
  std::vector<double> cut_signature_;  ///< the cut surface last drawn, to skip redrawing it
  std::size_t failures_ = 0;
  std::size_t front_failures_ = 0;
  std::uint64_t revision_ = 1;
  bool closed_ = true;
};

/// The physics nodes that carry a point of a triangle of `surface` (barycentric coordinates
/// in the triangle, summing to 1), with their weights (summing to 1): a force F there is
/// w * F on each node (the seed's 3.5: a collision force goes to its virtual element's DOFs).
[[nodiscard]] std::vector<std::pair<VertexId, double>> carriers(
    const VisualSurface& surface, std::size_t triangle, const std::array<double, 3>& barycentric);

}  // namespace incise
