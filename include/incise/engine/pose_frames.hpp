#pragma once
// Blade poses in the world and in the body's rest frame. The cutters cut the rest mesh, so a
// pose given where the user sees the body (the viewer's mouse, a tracked device) is carried
// back to the rest frame first, and a rest-frame pose (a scene's path) is drawn where the body
// is now: by the deformation of the element the blade is in, which is affine per linear
// tetrahedron, so the map is exact for any motion that is affine around the blade (rigid
// moves, stretches) and first-order accurate otherwise.

#include <optional>
#include <span>

#include "incise/core/types.hpp"
#include "incise/cut/blade.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// Which frame a tool pose is given in.
enum class PoseFrame : std::uint8_t { kRest, kWorld };

/// An affine map y = linear x + offset from one configuration of the mesh to another (m):
/// current positions to rest ones, or back.
struct RestMap {
  Mat3 linear = Mat3::Identity();  ///< the linear part
  Vec3 offset = Vec3::Zero();      ///< m
  /// The map applied to a point (m).
  [[nodiscard]] Vec3 operator()(const Vec3& x) const { return linear * x + offset; }
};

/// The map of element `tet` from its corners in `from` to its corners in `to`, if it is not
/// flat in either.
[[nodiscard]] std::optional<RestMap> element_map(const TetMesh& mesh, std::span<const Vec3> from,
                                                 std::span<const Vec3> to, TetId tet);

/// The map around a blade posed in configuration `from` into configuration `to`: of the
/// element holding the middle one of the blade's sample points that lie in the body, else of
/// the element nearest the blade; nothing for a mesh without a usable element. One pass over
/// the elements (0.6 ms at 50k tetrahedra).
[[nodiscard]] std::optional<RestMap> blade_map(const TetMesh& mesh, std::span<const Vec3> from,
                                               std::span<const Vec3> to, const BladePose& pose);

/// blade_map from the current positions x to the rest frame, for a blade held in the world.
[[nodiscard]] std::optional<RestMap> blade_rest_map(const TetMesh& mesh, std::span<const Vec3> x,
                                                    const BladePose& world);

/// The pose carried by `map`.
[[nodiscard]] BladePose mapped(const BladePose& pose, const RestMap& map);

}  // namespace incise
