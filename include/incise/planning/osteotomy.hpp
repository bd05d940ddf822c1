#pragma once
// Bone cutting and realignment: cut planes divide a bone surface into segments, rigid moves
// carry segments to new places, and moved segments are checked for interpenetration.
//
// A cut plane separates two triangles that share an edge when their centroids lie on
// opposite sides of it and both lie within its radius of its point (measured in the plane):
// a disc-shaped saw cut. Segments are the connected pieces that remain; pieces enclosing less
// than a least volume (the slivers a disc's rim or a jagged cut line leave) join the segment
// they share the most cut edges with.
//
// Moved segments are checked against each other: surfaces that come to cross away from the cut
// they share, or a segment reaching beyond that cut deeper than a tolerance, interpenetrate.
// Segments sliding along their cut, or hinged open about it, only touch there: contact.

#include <limits>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::planning {

/// An osteotomy: the bone cut by a plane, within a radius of its point (plan key
/// `osteotomies`).
struct CutPlane {
  Vec3 point = Vec3::Zero();                                ///< m
  Vec3 normal = Vec3::UnitZ();                              ///< unit
  double radius = std::numeric_limits<double>::infinity();  ///< m
};

/// The bone split into segments by the osteotomies.
struct BoneSegments {
  std::vector<int> triangle_segment;  ///< segment of each bone triangle, 0 .. count - 1
  int count = 0;                      ///< segments
  /// Triangles per segment.
  std::vector<int> sizes;
  /// Volume each segment encloses (length^3 in the surface's units), its cut closed flat
  /// (the surface closed by a cone from the centre of its cut edges).
  std::vector<double> volumes;
  int merged_fragments = 0;  ///< pieces below the least volume joined to a neighbour
  int small_isolated = 0;    ///< pieces below it with no neighbour: kept, reported
};

/// Segments the bone; pieces enclosing less than `least_volume` join the neighbour they share
/// the most cut edges with. Throws InputError for a plane with a zero normal.
[[nodiscard]] BoneSegments segment_bone(const SurfaceMesh& bone, std::span<const CutPlane> planes,
                                        double least_volume = 0.0);

/// A rigid motion x -> R (x - center) + center + translation.
struct RigidMove {
  Vec3 segment_near = Vec3::Zero();  ///< m: the moved segment is the one nearest this point
  Vec3 translation = Vec3::Zero();   ///< m
  Vec3 axis = Vec3::UnitZ();         ///< the rotation's axis (unit)
  double angle = 0.0;                ///< rad
  Vec3 center = Vec3::Zero();        ///< m
  /// Where the move takes x (m).
  [[nodiscard]] Vec3 apply(const Vec3& x) const;
};

/// The segment whose surface passes nearest to `point`.
[[nodiscard]] int nearest_segment(const SurfaceMesh& bone, const BoneSegments& segments,
                                  const Vec3& point);

/// Two moved segments that pass into each other.
struct Interpenetration {
  int first = 0;   ///< one segment
  int second = 0;  ///< the other
  /// Pairs of triangles that cross away from a cut the two segments share (contact on the cut
  /// is not counted).
  int crossing_triangle_pairs = 0;
  double depth = 0.0;  ///< m: how much further than before a moved one reaches into the
                       ///< other's side of the plane that separated them (0 when none did)
};

/// Positions of every bone vertex per segment after the moves: vertices on a cut belong to
/// several segments and are moved with each. Returns, per triangle, its three moved corners.
[[nodiscard]] std::vector<std::array<Vec3, 3>> moved_triangles(
    const SurfaceMesh& bone, const BoneSegments& segments,
    std::span<const RigidMove> segment_moves);

/// Where two triangles cross: the points where an edge of one passes through the other (none
/// when they do not cross; coplanar overlaps are not found). Pure.
[[nodiscard]] std::vector<Vec3> crossing_points(const std::array<Vec3, 3>& first,
                                                const std::array<Vec3, 3>& second);

/// Where the segments were cut apart, for the interpenetration checks: per pair of segments
/// that share cut edges, each plane with the two on opposite sides, the band about it that
/// holds their cut (its half width, m, the tolerance included) and how far each of the two
/// reached beyond it before any move. Depends on the bone, its segments and the planes only: a
/// planning session computes it once for all the moves it tries.
struct SegmentCuts {
  /// One plane that parts a pair of segments.
  struct Cut {
    std::size_t plane = 0;          ///< index into `planes`
    double half_width = 0.0;        ///< m
    double side[2] = {0.0, 0.0};    ///< which side each of the pair lies on (its sign)
    double before[2] = {0.0, 0.0};  ///< m: how far each reaches beyond the plane unmoved
  };
  std::vector<CutPlane> planes;  ///< the planes, normals made unit
  double tolerance = 0.0;        ///< m
  /// Per pair of segments (first < second), the planes that part them.
  std::map<std::pair<int, int>, std::vector<Cut>> cuts;
};

[[nodiscard]] SegmentCuts segment_cuts(const SurfaceMesh& bone, const BoneSegments& segments,
                                       std::span<const CutPlane> planes, double tolerance = 1e-6);

/// Pairs of segments, at least one of them moved, whose moved triangles cross where they did
/// not before the move (exact predicates; triangles that share a vertex are not compared)
/// outside the band about a cut the two share (the band holds the triangles along the cut,
/// which straddle it by up to an edge, plus `tolerance`; a crossing is inside when both
/// triangles are, or where they cross is), or of which a moved one reaches
/// further than before, by more than `tolerance` (m), beyond a plane that separates them (a cap
/// pushed into a closed bone crosses no surface). `segment_moves` holds one move per segment
/// (identity for those that stay).
[[nodiscard]] std::vector<Interpenetration> find_interpenetrations(
    const SurfaceMesh& bone, const BoneSegments& segments, std::span<const RigidMove> segment_moves,
    std::span<const CutPlane> planes, double tolerance = 1e-6);
/// The same with the cuts computed beforehand (segment_cuts of the same bone and segments).
[[nodiscard]] std::vector<Interpenetration> find_interpenetrations(
    const SurfaceMesh& bone, const BoneSegments& segments, std::span<const RigidMove> segment_moves,
    const SegmentCuts& cuts);

}  // namespace incise::planning
