// Where the blade is: the original tetrahedron each child descends from, material points
// (the blade tip carried with the body), the tetrahedron holding the tip and the active set.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "parallel_tests.hpp"
#include "triangle_index.hpp"

namespace incise {

using namespace cutter_detail;  // NOLINT(google-build-using-namespace): the cutter's own helpers

const Ancestry& SubdivisionCutter::ancestry(TetId tet) {
  Ancestry& entry = ancestry_[tet];
  if (entry.id < 0) {
    entry.id = static_cast<std::int32_t>(ancestor_codes_.size());
    ancestor_codes_.push_back(0);
    ancestor_presplit_.push_back(0);
    for (int a = 0; a < 4; ++a) {
      entry.corners[a] = mesh_.rest_position(mesh_.tet(tet)[a]);
    }
    entry.volume = std::abs(signed_volume(mesh_, tet));
  }
  return entry;
}

std::array<std::size_t, 7> SubdivisionCutter::accumulated_case_counts() const {
  std::array<std::size_t, 7> counts{};
  std::vector<char> seen(ancestor_codes_.size(), 0);
  // An original is partly cut while the blade is inside one of its descendants.
  std::vector<char> under_blade(ancestor_codes_.size(), 0);
  for (TetId t : active_) {
    const std::int32_t id = ancestry_[t].id;
    if (id >= 0) {
      under_blade[static_cast<std::size_t>(id)] = 1;
    }
  }
  for (std::size_t t = 0; t < mesh_.tet_count(); ++t) {
    const Ancestry& origin = ancestry_[static_cast<TetId>(t)];
    if (origin.id < 0 || seen[static_cast<std::size_t>(origin.id)] != 0) {
      continue;
    }
    seen[static_cast<std::size_t>(origin.id)] = 1;
    const std::uint8_t code = ancestor_codes_[static_cast<std::size_t>(origin.id)];
    if (code == 0) {
      continue;
    }
    const bool partial = under_blade[static_cast<std::size_t>(origin.id)] != 0;
    ++counts[static_cast<std::size_t>(cut_case_table()[cut_state_key(code, partial)].kind)];
  }
  return counts;
}

double SubdivisionCutter::min_volume_ratio_to_original() const {
  double ratio = 1.0;
  for (std::size_t t = 0; t < mesh_.tet_count(); ++t) {
    const Ancestry& origin = ancestry_[static_cast<TetId>(t)];
    if (origin.id >= 0 && origin.volume > 0.0) {
      ratio =
          std::min(ratio, std::abs(signed_volume(mesh_, static_cast<TetId>(t))) / origin.volume);
    }
  }
  return ratio;
}

SubdivisionCutter::MaterialPoint SubdivisionCutter::material_point(const Vec3& point) {
  MaterialPoint result;
  const TetId holder = locate(point);
  if (holder != kInvalidId) {
    result.vertices = mesh_.tet(holder);
    result.weights = weights_in(point, holder);
  }
  return result;
}

TetId SubdivisionCutter::locate(const Vec3& point) {
  grid_.query(point, point, scratch_);
  for (TetId t : scratch_) {
    const Tet& v = mesh_.tet(t);
    if (locate_in_tet(point, position(v[0]), position(v[1]), position(v[2]), position(v[3])) !=
        TetLocation::kOutside) {
      return t;
    }
  }
  return kInvalidId;
}

std::array<double, 4> SubdivisionCutter::weights_in(const Vec3& point, TetId tet) const {
  const Tet& v = mesh_.tet(tet);
  return barycentric_coordinates(point, position(v[0]), position(v[1]), position(v[2]),
                                 position(v[3]));
}

Vec3 SubdivisionCutter::current(const MaterialPoint& point, const Vec3& fallback) const {
  if (point.vertices[0] == kInvalidId) {
    return fallback;
  }
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    sum += point.weights[k] * position(point.vertices[k]);
  }
  return sum;
}

void SubdivisionCutter::track_point_tet() {
  const Vec3& tip = pose_.tip;
  auto holds = [&](TetId t) {
    const Tet& v = mesh_.tet(t);
    return locate_in_tet(tip, position(v[0]), position(v[1]), position(v[2]), position(v[3])) !=
           TetLocation::kOutside;
  };
  // The seed's search: the previous tetrahedron, then its neighbours, then everywhere (here
  // through the grid, so "everywhere" is local too).
  if (point_tet_ != kInvalidId && static_cast<std::size_t>(point_tet_) < mesh_.tet_count()) {
    if (holds(point_tet_)) {
      ++stats_.point_same;
      return;
    }
    for (TetId neighbor : mesh_.tet_neighbors(point_tet_)) {
      if (neighbor >= 0 && holds(neighbor)) {
        point_tet_ = neighbor;
        ++stats_.point_neighbor;
        return;
      }
    }
  }
  point_tet_ = locate(tip);
  ++(point_tet_ == kInvalidId ? stats_.point_outside : stats_.point_global);
}

void SubdivisionCutter::update_active_tets() {
  active_.clear();
  grid_.query(pose_.tip.cwiseMin(pose_.base), pose_.tip.cwiseMax(pose_.base), scratch_);
  std::vector<std::uint8_t> meets;
  test_each<TetId>(scratch_, meets, [&](TetId t) -> std::uint8_t {
    const Tet& v = mesh_.tet(t);
    return segment_intersects_tet(pose_.tip, pose_.base, position(v[0]), position(v[1]),
                                  position(v[2]), position(v[3]))
               ? 1
               : 0;
  });
  for (std::size_t i = 0; i < scratch_.size(); ++i) {
    if (meets[i] != 0) {
      active_.push_back(scratch_[i]);
    }
  }
}

}  // namespace incise
