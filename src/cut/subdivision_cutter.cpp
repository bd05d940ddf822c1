// The subdivision cutter's pipeline: construction, strokes, and one move of the blade
// (move_to): blade-line vertices, collision detection, edge splits, opening the cut.

#include "incise/cut/subdivision_cutter.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "cutter_helpers.hpp"
#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "triangle_index.hpp"

namespace incise {

using namespace cutter_detail;  // NOLINT(google-build-using-namespace): the cutter's own helpers

SubdivisionCutter::SubdivisionCutter(TetMesh& mesh, const CutterOptions& options,
                                     const VertexData<Vec3>* positions)
    : mesh_(mesh),
      options_(options),
      positions_(positions),
      grid_(mesh, positions),
      marks_(mesh),
      on_cut_(mesh, 0, VertexRule::kDefault),
      cut_offset_(mesh, 0.0, VertexRule::kDefault),
      ancestry_(mesh, Ancestry{}, TetRule::kCopy) {
  // The swept-surface index's finest cells: 1/32 of a mean edge.
  swept_ = std::make_unique<detail::TriangleIndex>(grid_.cell_size() / 32.0);
  if (!(options_.snap_fraction > 0.0 && options_.snap_fraction < 0.5)) {
    throw InputError("snap fraction must lie in (0, 0.5)");
  }
  if (positions_ != nullptr && positions_->size() != mesh.vertex_count()) {
    throw InputError("the cutter's positions do not belong to its mesh");
  }
  // A copy of a vertex on the cut is on the cut too.
  on_cut_.set_hook([](VertexData<char>& data, VertexId vertex, const VertexOrigin& origin) {
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      data[vertex] = data[origin.parents[0]];
    }
  });
  // A point between vertices lies no farther from a plane than the farthest of them.
  cut_offset_.set_hook([](VertexData<double>& data, VertexId vertex, const VertexOrigin& origin) {
    double offset = 0.0;
    for (int p = 0; p < origin.parent_count; ++p) {
      offset = std::max(offset, data[origin.parents[static_cast<std::size_t>(p)]]);
    }
    data[vertex] = offset;
  });
  // Every tetrahedron there is now is an original; children copy their parent's ancestry.
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    (void)ancestry(static_cast<TetId>(t));
  }
}

SubdivisionCutter::~SubdivisionCutter() = default;

void SubdivisionCutter::start(const BladePose& pose) {
  pose_ = pose;
  started_ = true;
  provisional_.clear();  // a new stroke: the last one's blade-line vertices stay where they are
  blade_line_placed_.reset();
  track_point_tet();
  update_active_tets();
  if (positions_ != nullptr) {
    tip_material_ = material_point(pose.tip);
    base_material_ = material_point(pose.base);
  }
}

void SubdivisionCutter::cut_along(const std::vector<BladePose>& path) {
  if (path.empty()) {
    return;
  }
  start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    move_to(path[i]);
  }
}

void SubdivisionCutter::move_to(const BladePose& pose) {
  if (!started_) {
    start(pose);
    return;
  }
  BladePose from = pose_;
  if (positions_ != nullptr) {
    from.tip = current(tip_material_, from.tip);
    from.base = current(base_material_, from.base);
  }
  pose_ = pose;
  ++stats_.moves;
  const auto triangles = swept_triangles(from, pose);
  for (const auto& triangle : triangles) {
    stats_.swept_area += area(triangle);
  }
  fresh_.clear();
  move_triangles_ = triangles;

  // The seed's frame, stage by stage: gc for the blade line, cd, then gc for the cut itself.
  auto start = Clock::now();
  if (positions_moved_) {
    grid_.refit();  // the body moved since the last cut
    positions_moved_ = false;
    blade_line_placed_.reset();
  }
  place_blade_line(from, pose, triangles);
  double gc_seconds = seconds_since(start);

  start = Clock::now();
  Contact contact = collide(triangles, pose);
  stats_.cd_seconds = seconds_since(start);
  if (options_.split == SplitMode::kGeneric && !contact.crossings.empty()) {
    start = Clock::now();
    presplit_generic(contact);
    gc_seconds += seconds_since(start);
    start = Clock::now();
    contact = detect(triangles);
    stats_.cd_seconds += seconds_since(start);
  }

  start = Clock::now();
  split_crossed_edges(contact);
  collapse_left_behind();
  insert_new_blade_line(pose, triangles);
  surface_.insert(surface_.end(), triangles.begin(), triangles.end());
  open_cut(triangles);
  stats_.gc_seconds = gc_seconds + seconds_since(start);
  stats_.total_cd_seconds += stats_.cd_seconds;
  stats_.total_gc_seconds += stats_.gc_seconds;
  stats_.max_move_seconds =
      std::max(stats_.max_move_seconds, stats_.cd_seconds + stats_.gc_seconds);

  track_point_tet();
  update_active_tets();
  if (positions_ != nullptr) {
    tip_material_ = material_point(pose.tip);
    base_material_ = material_point(pose.base);
  }
}

void SubdivisionCutter::place_blade_line(const BladePose& from, const BladePose& pose,
                                         const std::vector<std::array<Vec3, 3>>& triangles) {
  // Vertices where the blade line crosses faces, and at its tip: both ends of the swept
  // surface. The previous blade line was placed by the previous move already (unless the body
  // moved since or this is the first move); its vertices slide along with the blade. The new
  // blade line's vertices are put in after the crossings are split (insert_new_blade_line), so
  // a vertex the blade has left can be collapsed onto its crossing first.
  next_provisional_.clear();
  if (options_.open_under_blade && !triangles.empty()) {
    // The cut opened at every vertex of the last blade line (none slides on): that line is
    // put in again, unless it is the one the last move put in, with the body unmoved. Then
    // every point is a vertex on the cut already or lies on a feature of the cut, and nothing
    // would change (found so on the data meshes, the 50k viewer body and the soak's walks:
    // only a stroke's first move adds anything here).
    const bool placed = blade_line_placed_ && blade_line_placed_->tip == from.tip &&
                        blade_line_placed_->base == from.base;
    if (provisional_.empty() && !placed) {
      insert_blade_points(from, unit_normal(triangles.front()));
    }
    if (options_.slide_blade_points) {
      slide_blade_points(pose);
    }
  }
  provisional_.clear();
}

void SubdivisionCutter::insert_new_blade_line(const BladePose& pose,
                                              const std::vector<std::array<Vec3, 3>>& triangles) {
  if (options_.open_under_blade && !triangles.empty()) {
    sliding_ = options_.slide_blade_points;
    insert_blade_points(pose, unit_normal(triangles.back()));
    sliding_ = false;
    blade_line_placed_ = pose;
  }
}

SubdivisionCutter::Contact SubdivisionCutter::collide(
    const std::vector<std::array<Vec3, 3>>& triangles, const BladePose& pose) {
  Contact contact = detect(triangles);
  stats_.candidate_tets = contact.touched.size();
  record_swept(triangles, contact);
  classify(contact, pose);
  return contact;
}

void SubdivisionCutter::split_crossed_edges(const Contact& contact) {
  for (VertexId v : contact.snapped) {
    if (on_cut_[v] == 0) {
      mark_on_cut(v, distance_to_move(mesh_.rest_position(v)));
      ++stats_.vertices_snapped;
    }
    fresh_.push_back(v);  // met by this move: faces through it are decided again
  }
  for (const Crossing& crossing : contact.crossings) {
    if (on_cut_[crossing.a] != 0 && on_cut_[crossing.b] != 0) {
      continue;  // both ends already on the cut: the crossing is the cut itself
    }
    const EdgeId edge = mesh_.find_edge(crossing.a, crossing.b);
    INCISE_ASSERT(edge != kInvalidId, "a crossed edge vanished before it was split");
    const double t = mesh_.edge(edge)[0] == crossing.a ? crossing.t : 1.0 - crossing.t;
    const VertexId middle = split_edge(mesh_, edge, t);
    mark_on_cut(middle, 0.0);
    crossings_made_.push_back(middle);
    ++stats_.edges_split;
    stats_.min_volume_ratio = std::min(stats_.min_volume_ratio, std::min(t, 1.0 - t));
  }
}

bool SubdivisionCutter::sweep_reaches(TetId tet, int local_face) const {
  // A face only now on the cut has a corner or its centroid within its reach of this move's
  // sweep (at rest; parts_across_surface, sheet_bulge): within the largest offset of its
  // corners, or the bulge allowed for its size. The sweep is one image per tetrahedron it
  // touched where the body is deformed: there only their bounding box is asked.
  const Tet& v = mesh_.tet(tet);
  const auto& face = tet_local::kFaces[local_face];
  const std::array<Vec3, 3> p = rest_face(mesh_, tet, local_face);
  const double size = longest_edge(p);
  double offset = 0.0;
  for (int k : face) {
    offset = std::max(offset, cut_offset_[v[k]]);
  }
  const double reach = std::max(offset * (1.0 + 1e-9), kSweptSurfaceBulge * size) + 2e-9 * size;
  const auto near_sweep = [&](const Vec3& point) {
    if (((point - move_rest_low_).array() < -reach).any() ||
        ((point - move_rest_high_).array() > reach).any()) {
      return false;
    }
    return move_rest_triangles_.size() > 8 || distance_to(move_rest_triangles_, point) <= reach;
  };
  return near_sweep(p[0]) || near_sweep(p[1]) || near_sweep(p[2]) || near_sweep(centroid(p));
}

void SubdivisionCutter::open_cut(const std::vector<std::array<Vec3, 3>>& triangles) {
  // Decide the faces this move puts on the cut, then separate their corners where cut faces
  // part the tetrahedra around them. Faces through vertices put on the cut earlier are
  // decided again where this move swept (the surface may only now reach past them): the
  // undecided ones within reach of the sweep, found among the tetrahedra a cell (a mean edge)
  // around it. Blade-line vertices the cut opened at, in faces the blade has now left, are
  // collapsed first where they can be.
  if (move_sweep_ >= 0 && !triangles.empty()) {
    move_rest_low_ = Vec3::Constant(std::numeric_limits<double>::max());
    move_rest_high_ = -move_rest_low_;
    for (const auto& triangle : move_rest_triangles_) {
      for (const Vec3& corner : triangle) {
        move_rest_low_ = move_rest_low_.cwiseMin(corner);
        move_rest_high_ = move_rest_high_.cwiseMax(corner);
      }
    }
    Vec3 low = Vec3::Constant(std::numeric_limits<double>::max());
    Vec3 high = -low;
    for (const auto& triangle : triangles) {
      Vec3 triangle_low;
      Vec3 triangle_high;
      triangle_bounds(triangle, triangle_low, triangle_high);
      low = low.cwiseMin(triangle_low);
      high = high.cwiseMax(triangle_high);
    }
    const Vec3 margin = Vec3::Constant(grid_.cell_size());
    grid_.query(low - margin, high + margin, scratch_);
    if (collapse_opened_behind(scratch_)) {
      grid_.query(low - margin, high + margin, scratch_);  // the collapses reshaped some
    }
    for (TetId t : scratch_) {
      const Tet& v = mesh_.tet(t);
      for (int f = 0; f < 4; ++f) {
        const auto& face = tet_local::kFaces[f];
        if (mesh_.tet_neighbors(t)[f] >= 0 && !marks_.is_cut(t, f) && on_cut_[v[face[0]]] != 0 &&
            on_cut_[v[face[1]]] != 0 && on_cut_[v[face[2]]] != 0 && sweep_reaches(t, f)) {
          fresh_.insert(fresh_.end(), {v[face[0]], v[face[1]], v[face[2]]});
        }
      }
    }
  }
  std::vector<VertexId> candidates = mark_cut_faces();
  // Vertices on the cut where this move swept may be pinched or separable too.
  candidates.insert(candidates.end(), fresh_.begin(), fresh_.end());
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  // Separating a vertex parts the faces its tetrahedra shared through it, which may leave a
  // neighbour on the cut separable too: its neighbours join the work.
  std::unordered_set<VertexId> queued(candidates.begin(), candidates.end());
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const VertexId vertex = candidates[i];
    const auto first_copy = static_cast<VertexId>(mesh_.vertex_count());
    const std::size_t copies = separate(vertex);
    if (copies == 0) {
      continue;
    }
    stats_.vertices_duplicated += copies;
    // Copies made by the separation can be pinched too.
    around_parted(vertex, first_copy, scratch_vertices_);
    for (VertexId u : scratch_vertices_) {
      if ((on_cut_[u] != 0 || u >= first_copy) && queued.insert(u).second) {
        candidates.push_back(u);
      }
    }
  }
  resolve_pinched_edges(candidates);
  // Blade-line vertices the cut has opened at stay where they are; the others may slide.
  std::sort(separated_.begin(), separated_.end());
  for (const Provisional& point : next_provisional_) {
    if (!std::binary_search(separated_.begin(), separated_.end(), point.vertex)) {
      provisional_.push_back(point);
    }
  }
  separated_.clear();
}

}  // namespace incise
