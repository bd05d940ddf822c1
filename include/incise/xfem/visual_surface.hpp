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
//
// The picture never breaks: corefinement runs only on inputs that meet its preconditions
// (no self-intersection where the two surfaces meet), any exception it throws is caught, and
// the rebuilt surface is taken only when it is closed and 2-manifold along its edges (as the
// original was) with no flat triangle; otherwise the last good picture stays and failures()
// and last_failure() say so.

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/cut/tet_grid.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

class XfemCutter;

/// A point carried by a tetrahedron of the physics mesh: x = sum weights[k] * x(nodes[k]).
struct Embedding {
  Tet nodes{};                      ///< the physics nodes carrying the point
  std::array<double, 4> weights{};  ///< barycentric weights, summing to 1
};

/// A triangle surface embedded in the physics mesh (scene `visual`, `collision`): it moves with
/// the nodes that carry it and is cut along the polygons the XFEM cutter splits the elements by,
/// each piece kept a closed 2-manifold.
class VisualSurface {
 public:
  /// Embeds `points`/`triangles` (m, rest frame; outward, closed for a closed result) in the
  /// rest tetrahedra of `mesh`, which no cut has touched yet.
  VisualSurface(const TetMesh& mesh, std::vector<Vec3> points, std::vector<Triangle> triangles);
  ~VisualSurface();
  VisualSurface(const VisualSurface&) = delete;
  VisualSurface& operator=(const VisualSurface&) = delete;

  /// Follows the cut `cutter` has made in `mesh` so far (does nothing when no tetrahedron
  /// split since the last call: the picture opens where the physics splits). The surface is rebuilt
  /// from the original one, so it never accumulates error.
  void follow(const TetMesh& mesh, const XfemCutter& cutter);

  /// Current positions (m) of the surface's points, from the physics nodes' positions.
  [[nodiscard]] std::vector<Vec3> positions(std::span<const Vec3> nodes) const;
  [[nodiscard]] std::span<const Vec3> rest_points() const { return rest_points_; }  ///< m
  /// The surface's triangles now, cut faces included (outward).
  [[nodiscard]] std::span<const Triangle> triangles() const { return triangles_; }
  /// Per triangle: 1 when it lies on the cut surface, 0 on the original surface.
  [[nodiscard]] std::span<const std::uint8_t> on_cut() const { return on_cut_; }
  /// Per point: the nodes that carry it.
  [[nodiscard]] std::span<const Embedding> embeddings() const { return embedding_; }
  /// Points of the original surface outside the physics mesh.
  [[nodiscard]] std::size_t outside_points() const { return outside_; }
  /// Whether the original surface is closed (else no cut face is added: it has no inside).
  [[nodiscard]] bool original_closed() const { return closed_; }
  /// Updates that could not cut the picture (corefinement's preconditions not met or it gave
  /// up, or a result that was not a closed 2-manifold); the surface then kept its last good
  /// cut.
  [[nodiscard]] std::size_t failures() const { return failures_; }
  /// Why the last of those failed (empty when none has).
  [[nodiscard]] const std::string& last_failure() const { return last_failure_; }
  /// Grows each time the surface's triangles change (a renderer uploads them again then).
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

 private:
  /// The rest tetrahedron holding p, or the nearest one (`outside` set) for a point outside.
  TetId locate(const Vec3& p, bool* outside = nullptr) const;
  /// p's embedding, for a corner of a triangle: in the tetrahedron just inside the triangle
  /// (p plus a little of `inward`), in its element on the side of the cut that lies a little
  /// further towards `side` (`side_b`, if given: whether that is a split tetrahedron's second
  /// element).
  Embedding embed(const TetMesh& mesh, const XfemCutter* cutter, const Vec3& p, const Vec3& inward,
                  const Vec3& side, bool* side_b = nullptr) const;

  TetId locate_uncached(const Vec3& p, bool& is_outside) const;
  /// Extends the cut surface past the body's boundary far enough to cut a visual surface that
  /// sticks out of the body: a band extruded outwards in each polygon's plane from the cut's
  /// rim on the boundary.
  void add_skirt(std::vector<Vec3>& points, std::vector<Triangle>& triangles,
                 std::span<const std::uint64_t> edge_of_point) const;
  /// m: from p to the nearest point of the original surface.
  [[nodiscard]] double nearest_visual_distance(const Vec3& p) const;
  /// Drops triangles rounding made flat and welds the seam where the picture's cut runs past
  /// the physics' front.
  void tidy();
  /// Welds points a rounding error apart that the same nodes carry.
  void weld_near_points();
  /// Pairs the triangles of edges used more than twice by their order about the edge and
  /// copies each point once per fan around it: the same surface, a 2-manifold.
  void split_non_manifold(const TetMesh& mesh);
  /// Closes pockets of no volume: a flat triangle and its neighbour across its longest side
  /// whose third points lie at one place are dropped, and those points welded.
  void close_flat_pockets();
  /// Gives each pair of triangles that still shares its edge's points with another pair a
  /// point of its own in the edge's middle (`twin`: each half-edge's partner, 3 t + k).
  void split_shared_edges(const TetMesh& mesh, std::span<const std::size_t> twin);

  /// The visual surface and the cut surface, corefined.
  struct Corefined;
  /// Whether corefinement's preconditions hold for the pair: the cut surface does not
  /// intersect itself, nor meets the visual one where that intersects itself.
  [[nodiscard]] bool corefinable(const Corefined& pair) const;
  /// The picture from a corefined pair: points embedded on their sides, cut faces inside.
  void rebuild(const TetMesh& mesh, const XfemCutter& cutter, const Corefined& pair);

  /// The original surface as CGAL's mesh and its inside test, made once (every update starts
  /// from them).
  struct CgalCache;
  std::unique_ptr<CgalCache> cgal_;
  TetMesh rest_mesh_;  ///< the physics mesh before any cut (its tetrahedra are the rest ones)
  std::unique_ptr<TetGrid> grid_;
  double nudge_ = 0.0;  ///< m: how far past a point its side is read
  double reach_ = 0.0;  ///< m: how far the surface sticks out of the body at most
  mutable std::map<std::array<double, 3>, std::pair<TetId, bool>> located_;
  std::set<std::array<VertexId, 3>> rest_boundary_;        ///< sorted vertex ids of boundary faces
  std::unordered_set<std::uint64_t> rest_boundary_edges_;  ///< edge_key of boundary edges
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
  std::size_t failures_ = 0;
  std::string last_failure_;
  SurfaceEdgeCheck original_edges_;  ///< a rebuilt picture may be no less closed than this
  std::size_t original_flat_ = 0;    ///< flat triangles the original kept (unflippable ones)
  std::uint64_t revision_ = 1;
  bool closed_ = true;
};

/// Removes pairs of triangles on the same three points facing opposite ways (they enclose
/// nothing), keeping `on_cut` in step; returns the pairs removed.
std::size_t remove_coincident_pairs(std::vector<Triangle>& triangles,
                                    std::vector<std::uint8_t>& on_cut);
/// Flips each flat triangle (collinear corners) with its neighbour across its longest edge,
/// which leaves the same surface without it, where the new edge does not exist yet; returns
/// the flips made.
std::size_t flip_flat_triangles(std::span<const Vec3> points, std::vector<Triangle>& triangles,
                                std::vector<std::uint8_t>& on_cut);
/// Triangles with (next to) no area: height over the longest edge below 1e-9 of that edge.
[[nodiscard]] std::size_t count_flat_triangles(std::span<const Vec3> points,
                                               std::span<const Triangle> triangles);
/// What keeps a triangle surface from being closed and 2-manifold along its edges (no worse
/// than `allowed`), with no more than `allowed_flat` flat triangles; empty when nothing does.
[[nodiscard]] std::string closed_manifold_problem(std::span<const Vec3> points,
                                                  std::span<const Triangle> triangles,
                                                  const SurfaceEdgeCheck& allowed,
                                                  std::size_t allowed_flat = 0);

/// The physics nodes that carry a point of a triangle of `surface` (barycentric coordinates
/// in the triangle, summing to 1), with their weights (summing to 1): a force F there is
/// w * F on each node (the seed's 3.5: a collision force goes to its virtual element's DOFs).
[[nodiscard]] std::vector<std::pair<VertexId, double>> carriers(
    const VisualSurface& surface, std::size_t triangle, const std::array<double, 3>& barycentric);

}  // namespace incise
