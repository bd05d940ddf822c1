#pragma once
// Writing a plan's results in millimetres for ParaView and 3D Slicer (private to planning).

#include <filesystem>
#include <span>
#include <vector>

#include "incise/io/mesh_io.hpp"
#include "incise/planning/layered_tissue.hpp"
#include "incise/planning/osteotomy.hpp"

namespace incise::planning {

/// A skin surface (positions in m written in mm); with `before`, point data `displacement`
/// (mm) and `displacement_magnitude` (mm).
void write_surface_mm(const std::filesystem::path& path, std::span<const Vec3> points,
                      std::span<const Triangle> triangles, std::span<const Vec3> before,
                      std::span<const int> cell_segment);

/// The bone with cell data `segment`; each segment moved by its move (none: as it is), so
/// vertices on a cut appear once per segment.
void write_bone_mm(const std::filesystem::path& path, const SurfaceMesh& bone,
                   const BoneSegments& segments, std::span<const RigidMove> segment_moves);

/// The layered model as VTK wedges at positions x (m, written in mm), point data `kind`
/// (0 soft, 1 bone, 2 boundary), `layer` and `displacement` (mm), cell data `layer`.
void write_tissue_vtu_mm(const std::filesystem::path& path, const LayeredTissue& tissue,
                         std::span<const Vec3> x);

}  // namespace incise::planning
