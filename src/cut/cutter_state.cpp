// Checkpoints of the subdivision cutter: its own state (what follows the mesh is saved with
// the mesh's observers).

#include <algorithm>
#include <cmath>
#include <limits>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "triangle_index.hpp"

namespace incise {

using namespace cutter_detail;  // NOLINT(google-build-using-namespace): the cutter's own helpers

void SubdivisionCutter::save_state(StateWriter& out) const {
  out.tag("subdivision cutter");
  out.value(pose_);
  out.value(started_);
  out.value(positions_moved_);
  out.value(point_tet_);
  out.value(tip_material_);
  out.value(base_material_);
  out.value(stats_);
  out.values(active_);
  out.values(provisional_);
  out.values(move_triangles_);
  out.values(move_rest_triangles_);
  out.values(surface_);
  out.values(ancestor_codes_);
  out.values(ancestor_presplit_);
  swept_->save_state(out);
}

void SubdivisionCutter::load_state(StateReader& in) {
  in.tag("subdivision cutter");
  pose_ = in.value<BladePose>("blade pose");
  started_ = in.value<bool>("stroke started");
  positions_moved_ = in.value<bool>("positions moved");
  point_tet_ = in.value<TetId>("tip tetrahedron");
  tip_material_ = in.value<MaterialPoint>("tip material point");
  base_material_ = in.value<MaterialPoint>("base material point");
  stats_ = in.value<CutStats>("cut statistics");
  active_ = in.values<TetId>("active tetrahedra");
  provisional_ = in.values<Provisional>("blade-line vertices");
  move_triangles_ = in.values<std::array<Vec3, 3>>("last swept triangles");
  move_rest_triangles_ = in.values<std::array<Vec3, 3>>("last swept triangles at rest");
  surface_ = in.values<std::array<Vec3, 3>>("swept surface");
  ancestor_codes_ = in.values<std::uint8_t>("cut-edge codes");
  ancestor_presplit_ = in.values<char>("generic splits");
  swept_->load_state(in);
  const auto tets = static_cast<TetId>(mesh_.tet_count());
  const auto vertices = static_cast<VertexId>(mesh_.vertex_count());
  bool ok = point_tet_ >= kInvalidId && point_tet_ < tets;
  for (TetId t : active_) {
    ok = ok && t >= 0 && t < tets;
  }
  for (const Provisional& p : provisional_) {
    ok = ok && p.vertex >= 0 && p.vertex < vertices && p.count >= 3 && p.count <= 4;
    for (int k = 0; k < p.count; ++k) {
      ok = ok && p.corners[static_cast<std::size_t>(k)] >= 0 &&
           p.corners[static_cast<std::size_t>(k)] < vertices;
    }
  }
  if (!ok) {
    in.fail("the cutter", "it names tetrahedra or vertices the mesh does not have");
  }
  fresh_.clear();
  separated_.clear();
  move_sweep_ = -1;
  next_provisional_.clear();
  blade_line_placed_.reset();  // not saved: the next move puts the blade line in again
}

}  // namespace incise
