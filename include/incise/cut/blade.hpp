#pragma once
// The virtual scalpel: a blade segment from its tip to its base (the seed's thin line), posed
// over time. Two consecutive poses sweep a surface (two triangles).

#include <array>
#include <filesystem>
#include <vector>

#include "incise/core/types.hpp"

namespace incise {

/// The blade at one instant: the segment from its tip to its base.
struct BladePose {
  double time = 0.0;  ///< s
  Vec3 tip;           ///< m
  Vec3 base;          ///< m
};

/// The blade in the tool's own frame, as a tracked device reports the tool: the tip at the
/// frame's origin, the base `length` along the unit `axis`.
struct BladeGeometry {
  double length = 0.05;       ///< m
  Vec3 axis = Vec3::UnitZ();  ///< unit, in the tool frame
};

/// A tool pose: rotation and translation (m) mapping tool-frame points into the world.
struct ToolFrame {
  Mat3 rotation = Mat3::Identity();  ///< tool frame to world
  Vec3 translation = Vec3::Zero();   ///< m, the tool frame's origin in the world
};

/// Where the blade is when the tool frame is `frame`.
[[nodiscard]] BladePose blade_in_frame(const ToolFrame& frame, const BladeGeometry& blade);
/// A tool frame that puts the blade's tip at `pose.tip` and its axis along base - tip (the
/// smallest rotation from the geometry's axis); the pose's length is not checked.
[[nodiscard]] ToolFrame frame_of_blade(const BladePose& pose, const BladeGeometry& blade);

/// The triangles swept by the blade between two poses: (tip0, base0, base1) and
/// (tip0, base1, tip1). Degenerate ones (a blade that did not move) are dropped.
[[nodiscard]] std::vector<std::array<Vec3, 3>> swept_triangles(const BladePose& from,
                                                               const BladePose& to);

/// Reads a tool path: a CSV file with the header t,tip_x,tip_y,tip_z,base_x,base_y,base_z
/// (s, m) and times that never decrease. Errors name the file and line.
[[nodiscard]] std::vector<BladePose> read_blade_path(const std::filesystem::path& path);
void write_blade_path(const std::filesystem::path& path, const std::vector<BladePose>& poses);

}  // namespace incise
