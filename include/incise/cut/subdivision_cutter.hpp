#pragma once
// Progressive cutting by subdivision (after Bielser et al., seed 000, sections 3-4), without
// the seed's cracks: every mesh edge the blade's swept surface crosses is split where it
// crosses, conformingly (every tetrahedron around the edge is split, so no hanging node is
// left); faces that then lie on the swept surface between tetrahedra on its two sides are cut
// faces; and every vertex on the cut is duplicated once for each group of tetrahedra that cut
// faces separate around it. Vertices on the crack front keep their tetrahedra together, so a
// partial cut opens as a slit that follows the blade frame by frame. Intersections use exact
// predicates; crossings closer to an edge end than a fraction of the edge snap to the vertex,
// which bounds how thin a child can get.
//
// Which faces are cut is decided once, in the move that sweeps them, and remembered
// topologically (CutFaceMarks): later splits of a cut face pass the mark on exactly, so no
// later decision depends on whether a point computed in floating point lies on a plane.
// Each tetrahedron next to a candidate face takes one side of the swept surface (that of its
// centroid), so a flat tetrahedron whose corners all lie on the cut joins one side instead of
// falling out as a shard.
//
// The cutter only edits the mesh: physics attached through attribute containers follows.

#include <initializer_list>
#include <memory>
#include <optional>
#include <vector>

#include "incise/core/stamped_set.hpp"
#include "incise/cut/blade.hpp"
#include "incise/cut/cut_cases.hpp"
#include "incise/cut/cut_face_marks.hpp"
#include "incise/cut/tet_grid.hpp"
#include "incise/mesh/attributes.hpp"

namespace incise {

namespace detail {
class TriangleIndex;
}

/// How a tetrahedron the blade crosses is split.
enum class SplitMode {
  /// Only the edges the cut crosses are split (conformingly), so each case takes the fewest
  /// children it needs.
  kMinimal,
  /// The seed's generic split (its Fig. 4): every edge of a cut tetrahedron is split (at the
  /// crossing, else at the midpoint) and every face at a face point, before the cut itself is
  /// resolved as in kMinimal. Conforming, so neighbours are split along too. For comparison.
  kGeneric,
};

/// How the subdivision cutter splits and opens (scene key `cutter`).
struct CutterOptions {
  /// A crossing within this fraction of an edge's length from an end snaps to that vertex
  /// instead of splitting the edge (and a blade point with a barycentric coordinate below it
  /// snaps onto the face, edge or vertex); a split child keeps at least this fraction of its
  /// parent's volume.
  double snap_fraction = 0.1;
  SplitMode split = SplitMode::kMinimal;  ///< which tetrahedra a move splits, and how
  /// Insert vertices on the blade line (face crossings and the tip), so the tetrahedra holding
  /// the blade open up to it during the move rather than after the blade has left them.
  bool open_under_blade = true;
  /// Leave out a blade point within the snap distance (of the original tetrahedron) of a
  /// vertex already on the cut, so tiny steps do not keep adding vertices (fewer tetrahedra,
  /// but the wound may then trail the blade by up to about twice the snap distance).
  bool merge_blade_points = false;
  /// Slide the blade-line vertices of the previous pose along with the blade (moving them in
  /// the material, with their tetrahedra) instead of adding new ones every pose, so the number
  /// of tetrahedra does not grow with how finely the blade's path is sampled. A vertex stays
  /// where it is (and a new one is added) when sliding would invert or flatten a tetrahedron
  /// around it, change the body's boundary, or once the cut has opened at it.
  bool slide_blade_points = true;
};

/// What the cutter did: the last move's times and counts, and totals over every move.
struct CutStats {
  // Last move.
  double cd_seconds = 0.0;         ///< collision detection: finding tets and crossing edges (s)
  double gc_seconds = 0.0;         ///< topology and geometry changes: splits and separation (s)
  std::size_t candidate_tets = 0;  ///< tets the swept surface touched in the last move
  // Totals.
  std::size_t moves = 0;        ///< blade moves (move_to calls)
  std::size_t sweeps = 0;       ///< moves that swept some surface inside the body (the blade moved)
  std::size_t edges_split = 0;  ///< edges split where the cut crosses them
  std::size_t vertices_snapped = 0;     ///< crossings snapped to a vertex within the snap fraction
  std::size_t vertices_duplicated = 0;  ///< vertex copies made where cut faces part tetrahedra
  std::size_t blade_vertices = 0;       ///< vertices inserted on the blade line
  std::size_t blade_slides = 0;         ///< blade-line vertices slid along with the blade
  /// Blade-line vertices the blade left behind, collapsed onto the edge crossing next to them.
  std::size_t blade_points_collapsed = 0;
  std::size_t blade_points_left_out = 0;  ///< not inserted: they would thin a tet below 1e-4
  std::size_t generic_splits = 0;  ///< tetrahedra given the generic split (SplitMode::kGeneric)
  std::size_t cut_faces = 0;       ///< faces found on the cut (each counted once)
  std::size_t shards_kept = 0;     ///< cut faces given back so a thin sliver is not cut out
  double cut_area = 0.0;    ///< rest area of the faces found on the cut, each once, one side (m^2)
  double swept_area = 0.0;  ///< area swept by the blade (m^2)
  /// Smallest child / parent volume ratio of any split (at the split: a blade-line vertex
  /// sliding later reshapes the tetrahedra around it).
  double min_volume_ratio = 1.0;
  // The active point tetrahedron (the one holding the blade tip), as the seed tracks it.
  std::size_t point_same = 0;      ///< tip still in the previous tetrahedron
  std::size_t point_neighbor = 0;  ///< found among its face neighbours
  std::size_t point_global = 0;    ///< found through the spatial grid
  std::size_t point_outside = 0;   ///< tip outside the mesh
  double total_cd_seconds = 0.0;   ///< collision detection over every move (s)
  double total_gc_seconds = 0.0;   ///< topology and geometry changes over every move (s)
  double max_move_seconds = 0.0;   ///< the most expensive move, cd + gc (s)
  /// Tetrahedra cut per move, by the seed's case (index: CutCase): the cut-edge code of the
  /// edges the move crossed, partial while the blade is still inside the tetrahedron.
  std::array<std::size_t, 7> case_counts{};
};

/// What a tetrahedron descends from: every child of a split inherits its original
/// tetrahedron's id, rest corners and volume, so cut-edge codes accumulate on the original
/// across moves (as the seed's per-tetrahedron state does) and child volumes can be compared
/// with the original's, however often it was cut.
struct Ancestry {
  std::int32_t id = -1;  ///< the original tetrahedron (-1 until first seen)
  double volume = 0.0;   ///< its rest volume (m^3)
  /// Its rest corners (m).
  std::array<Vec3, 4> corners{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
};

/// The seed's progressive subdivision cutter: a blade moved pose by pose splits the tetrahedra
/// it sweeps, crack-free, and opens the cut behind it (Bielser et al.). It edits the mesh it
/// was given; models that observe the mesh follow each edit.
class SubdivisionCutter {
 public:
  /// Cuts `mesh` where the blade meets its rest positions, or its current `positions` (m) when
  /// given: a VertexData of the same mesh that outlives the cutter.
  explicit SubdivisionCutter(TetMesh& mesh, const CutterOptions& options = {},
                             const VertexData<Vec3>* positions = nullptr);
  ~SubdivisionCutter();
  SubdivisionCutter(const SubdivisionCutter&) = delete;
  SubdivisionCutter& operator=(const SubdivisionCutter&) = delete;

  /// Tells the cutter that the current positions moved (after a physics step): its spatial
  /// index is refitted before the next move. Not needed when cutting on rest positions.
  void positions_changed() { positions_moved_ = positions_ != nullptr; }
  /// Also keeps every tetrahedron right side out in `deformed` (m; a VertexData of the same
  /// mesh that outlives the cutter, or null), when the cutter cuts other positions (its rest
  /// positions, as the engine's does): a blade-line slide or a collapse that would turn a
  /// tetrahedron inside out there is not made. The split itself cannot: its points are the
  /// same combinations of corners in every configuration. The cutter only reads `deformed`.
  void keep_right_side_out_in(const VertexData<Vec3>* deformed) { deformed_ = deformed; }
  /// The position the cutter intersects for a vertex (m).
  [[nodiscard]] const Vec3& position(VertexId vertex) const { return grid_.position(vertex); }

  /// Puts the blade at a pose without cutting.
  void start(const BladePose& pose);
  /// Moves the blade from its current pose to `pose` and cuts what it swept.
  void move_to(const BladePose& pose);
  /// Runs a whole path: start at the first pose, then move through the others.
  void cut_along(const std::vector<BladePose>& path);

  [[nodiscard]] const CutStats& stats() const { return stats_; }  ///< what it did so far
  /// The tetrahedron holding the blade tip, or kInvalidId when the tip is outside.
  [[nodiscard]] TetId active_point_tet() const { return point_tet_; }
  /// Checkpoints: the cut so far (swept surface, blade, pending blade-line vertices,
  /// statistics). What follows the mesh (marks, grid, per-vertex and per-tet data) is saved
  /// with the mesh's observers.
  void save_state(StateWriter& out) const;
  /// Restores what save_state() wrote, onto the same mesh restored from the same checkpoint.
  void load_state(StateReader& in);
  /// Tetrahedra the blade segment intersects now (the seed's active tetrahedra).
  [[nodiscard]] const std::vector<TetId>& active_tets() const { return active_; }
  /// Whether a vertex lies on the cut surface.
  [[nodiscard]] bool on_cut(VertexId vertex) const { return on_cut_[vertex] != 0; }
  /// The triangles the blade swept so far (m, where it met the body).
  [[nodiscard]] const std::vector<std::array<Vec3, 3>>& swept_surface() const { return surface_; }
  /// The faces found on the cut (opened, or still joined at the crack front).
  [[nodiscard]] const CutFaceMarks& cut_faces() const { return marks_; }
  [[nodiscard]] bool started() const { return started_; }        ///< whether the blade was placed
  [[nodiscard]] const BladePose& pose() const { return pose_; }  ///< the blade's last pose
  /// Cut-edge code (bit k: the original's local edge k was crossed) accumulated over all
  /// moves, per original tetrahedron id.
  [[nodiscard]] const std::vector<std::uint8_t>& accumulated_codes() const {
    return ancestor_codes_;
  }
  /// Original tetrahedra by the seed's case of their accumulated code (index: CutCase),
  /// partial while the blade is still inside them.
  [[nodiscard]] std::array<std::size_t, 7> accumulated_case_counts() const;
  /// Smallest volume of a tetrahedron over the volume of the original it descends from.
  [[nodiscard]] double min_volume_ratio_to_original() const;

 private:
  /// A blade-line vertex that may still slide with the blade (not separated): the corners of
  /// the face (count 3) or tetrahedron (count 4) it was put in, where it stays.
  struct Provisional {
    VertexId vertex = kInvalidId;
    std::array<VertexId, 4> corners{kInvalidId, kInvalidId, kInvalidId, kInvalidId};
    int count = 0;
  };
  struct Crossing {
    VertexId a;
    VertexId b;
    double t;  ///< from a (0) to b (1)
  };
  /// What the swept triangles meet: tetrahedra, crossed edges, vertices they snap to.
  struct Contact {
    std::vector<TetId> touched;
    std::vector<Crossing> crossings;
    std::vector<VertexId> snapped;
  };
  // The stages of one move (move_to), in order.
  /// Blade-line vertices of the previous pose slid to the new one where they can (or put in,
  /// at a stroke's first move).
  void place_blade_line(const BladePose& from, const BladePose& pose,
                        const std::vector<std::array<Vec3, 3>>& triangles);
  /// Blade-line vertices put in where the new pose's blade line needs them.
  void insert_new_blade_line(const BladePose& pose,
                             const std::vector<std::array<Vec3, 3>>& triangles);
  /// Collision detection, the swept surface recorded, cut-edge codes classified.
  [[nodiscard]] Contact collide(const std::vector<std::array<Vec3, 3>>& triangles,
                                const BladePose& pose);
  /// Snapped vertices put on the cut; crossed edges split at the crossing.
  void split_crossed_edges(const Contact& contact);
  /// Blade-line vertices the blade has just left (their face or tetrahedron) collapsed onto a
  /// crossing this move split on that feature's boundary, where that keeps every tetrahedron
  /// around them sound: the vertex the wound needed under the blade is let go of once the
  /// blade is past it, so what is left does not depend on how finely the path is sampled.
  void collapse_left_behind();
  /// Collapses a blade-line vertex onto a vertex next to it if every tetrahedron around it
  /// stays positive, no worse than before and filling the same space; true when done.
  bool try_collapse(VertexId vertex, VertexId target);
  /// Whether collapsing `vertex` onto `target` keeps the boundary around it as it is: flat,
  /// the same area, the target in its plane.
  [[nodiscard]] bool boundary_kept_flat(VertexId vertex, VertexId target) const;
  /// Blade-line vertices the cut opened at (and their copies) in the tetrahedra `around`, in
  /// faces the blade has left: collapsed onto a vertex of the cut on their face's boundary
  /// where they can. True if any was (the tetrahedra changed).
  bool collapse_opened_behind(const std::vector<TetId>& around);
  /// Where a blade-line vertex leaves its face: the edge (a, b) and the place t (0 at a, 1 at
  /// b) where the cut will cross it.
  struct Handover {
    VertexId vertex = kInvalidId;
    VertexId a = kInvalidId;
    VertexId b = kInvalidId;
    double t = 0.0;
    double ahead = 0.0;  ///< m: how far the exit lies ahead of this move's swept surface
    double size = 0.0;   ///< m: the face's longest edge
  };
  /// The exit of a blade-line vertex from its face, given the new blade line's weights in that
  /// face (`next`); nothing when it cannot be told or lies too far ahead of the blade.
  [[nodiscard]] std::optional<Handover> exit_of(const Provisional& point,
                                                const std::array<double, 4>& next) const;
  /// The vertex at an exit: one on the edge within the snap fraction, else the edge piece split
  /// there; kInvalidId when there is none.
  VertexId vertex_at_exit(const Handover& exit);
  /// Blade-line vertices in faces the blade is leaving collapsed onto their exits, where they
  /// can be; the others are left behind (collapse_left_behind tries again after the crossings).
  void hand_over(const std::vector<std::pair<Provisional, std::array<double, 4>>>& leaving);
  /// Faces on the cut marked, vertices separated, pinched edges resolved.
  void open_cut(const std::vector<std::array<Vec3, 3>>& triangles);
  /// Whether an interior face with its corners on the cut may only now lie on it: this move's
  /// sweep passes within its reach.
  [[nodiscard]] bool sweep_reaches(TetId tet, int local_face) const;

  [[nodiscard]] Contact detect(const std::vector<std::array<Vec3, 3>>& triangles);
  void classify(const Contact& contact, const BladePose& pose);
  /// Inserts vertices on the blade line of `pose`; `normal` (unit) is that of the swept surface
  /// there.
  void insert_blade_points(const BladePose& pose, const Vec3& normal);
  void insert_point(const Vec3& point, const Vec3& normal);
  /// Whether putting a point with these weights into `holder` (on its face or edge where
  /// weights are 0) leaves every child above the quality floor.
  [[nodiscard]] bool splits_well(TetId holder, const std::array<double, 4>& weights) const;
  /// Moves each blade-line vertex of the previous pose to where the blade line of `pose`
  /// meets the face (or tetrahedron, for the tip) it was put in, if every tetrahedron around
  /// it stays positive and no thinner than it was (or than a floor).
  void slide_blade_points(const BladePose& pose);
  /// Rest area (m^2) of the cut faces through a vertex that the cut has not opened at.
  [[nodiscard]] double cut_area_around(VertexId vertex) const;
  /// The same over the faces through any of `vertices`, each counted once.
  [[nodiscard]] double cut_area_through(std::initializer_list<VertexId> vertices) const;
  void presplit_generic(const Contact& contact);
  /// Puts a vertex on the cut (remembering how far it lies from the swept surface) and records
  /// the original edge it lies in, if any.
  /// `offset` (m, at rest): its distance from the swept surface.
  void mark_on_cut(VertexId vertex, double offset);
  /// Distance (m) at rest from a point to this move's swept triangles.
  [[nodiscard]] double distance_to_move(const Vec3& rest_point) const;
  /// Records this move's swept triangles at rest (through the tetrahedra they touch when
  /// cutting in the deformed configuration).
  void record_swept(const std::vector<std::array<Vec3, 3>>& triangles, const Contact& contact);
  /// Marks the faces that this move puts on the cut: faces through vertices put on it (or met)
  /// this move, with all corners on the cut, lying on the swept surface (all of it, at rest:
  /// a large face can span many moves), between tetrahedra on its two sides. Returns the
  /// corners of the faces marked.
  std::vector<VertexId> mark_cut_faces();
  /// Whether an interior face with all corners on the cut lies on the swept surface and parts
  /// the tetrahedra on its two sides (decided at rest).
  [[nodiscard]] bool parts_across_surface(TetId tet, int local_face, TetId neighbor) const;
  /// How far (m) the face may bulge off the swept surface: 0 unless its corners lie on one
  /// continuous sheet (their nearest swept triangles come from consecutive sweeps that all pass
  /// near the face), else a small fraction of the face's size.
  [[nodiscard]] double sheet_bulge(const std::array<Vec3, 3>& face,
                                   const std::array<VertexId, 3>& corners) const;
  /// Thin regions that this move's cut faces would cut out (volume over cut area below the snap
  /// distance: slivers along the cut, not pieces the blade enclosed) are given back to the
  /// side they share most cut area with, by taking back the marks between them.
  void keep_no_shards();
  /// The side (-1, +1) of the swept surface nearest `near_point` (m, at rest) that a
  /// tetrahedron's centroid is on; 0 when no swept triangle is within `radius` (m).
  [[nodiscard]] int swept_side(TetId tet, const Vec3& near_point, double radius) const;
  /// How far (m, at rest) a point of a cut face may lie from the swept surface: its corners'
  /// offsets, plus round-off.
  [[nodiscard]] double face_reach(TetId tet, int local_face) const;
  void track_point_tet();
  void update_active_tets();
  std::size_t separate(VertexId vertex);
  /// The ancestry of a tetrahedron, assigning a new original to one added afresh.
  const Ancestry& ancestry(TetId tet);
  void resolve_pinched_edges(std::vector<VertexId> vertices);
  /// Into `around`: the vertices of the tetrahedra at a vertex just parted and at its copies
  /// (ids from `first_copy` on), with repeats: where parting it can change what is separable
  /// or pinched.
  void around_parted(VertexId vertex, VertexId first_copy, std::vector<VertexId>& around) const;

  /// A point carried by the material: barycentric weights on four vertices (or none, outside).
  struct MaterialPoint {
    std::array<VertexId, 4> vertices{kInvalidId, kInvalidId, kInvalidId, kInvalidId};
    std::array<double, 4> weights{};
  };
  [[nodiscard]] MaterialPoint material_point(const Vec3& point);
  /// A tetrahedron holding `point` (at the positions the cutter intersects), or kInvalidId.
  [[nodiscard]] TetId locate(const Vec3& point);
  /// Barycentric coordinates of `point` in `tet` (at the positions the cutter intersects).
  [[nodiscard]] std::array<double, 4> weights_in(const Vec3& point, TetId tet) const;
  /// Where a material point is now; `fallback` (m) when it was outside the body.
  [[nodiscard]] Vec3 current(const MaterialPoint& point, const Vec3& fallback) const;

  TetMesh& mesh_;
  CutterOptions options_;
  const VertexData<Vec3>* positions_;
  const VertexData<Vec3>* deformed_ = nullptr;  ///< see keep_right_side_out_in
  TetGrid grid_;
  bool positions_moved_ = false;
  /// The blade's tip and base at the last pose, carried by the body as it moves (deformed
  /// configuration): the next move sweeps from where that material is now, so the swept
  /// surface starts at the crack front rather than where the front was.
  MaterialPoint tip_material_;
  MaterialPoint base_material_;
  /// The faces on the cut, following every edit.
  CutFaceMarks marks_;
  /// Where the blade went, at rest (in material space): the swept triangles themselves when
  /// cutting at rest; in the deformed configuration, their images under the affine map from
  /// current to rest positions of each tetrahedron they touched, valid inside its rest bounds
  /// (exact there, since the deformation is linear on each tetrahedron).
  std::unique_ptr<detail::TriangleIndex> swept_;
  /// This move's swept triangles, where the cutter intersects.
  std::vector<std::array<Vec3, 3>> move_triangles_;
  /// This move's part of it (unbounded images).
  std::vector<std::array<Vec3, 3>> move_rest_triangles_;
  /// Those of the last pose, and of this one (while insert_point records them).
  std::vector<Provisional> provisional_;
  std::vector<Provisional> next_provisional_;
  /// The pose whose blade line the last move of this stroke put in, while the body has not
  /// moved since: the next move starts from it and need not put it in again.
  std::optional<BladePose> blade_line_placed_;
  /// Blade-line vertices whose feature the blade left this move, and the edge crossings this
  /// move split: collapse_left_behind's input.
  std::vector<Provisional> left_behind_;
  std::vector<VertexId> crossings_made_;
  bool sliding_ = false;
  /// Vertices separate() duplicated during this move.
  std::vector<VertexId> separated_;
  /// Vertices put on the cut (or found on it) during this move.
  std::vector<VertexId> fresh_;
  std::vector<VertexId> scratch_vertices_;  ///< around_parted's output, reused
  /// Faces marked by the last mark_cut_faces(): (tetrahedron, local face).
  std::vector<std::pair<TetId, int>> marked_;
  VertexData<char> on_cut_;
  /// How far (m) a vertex on the cut lay from the swept surface when it was put there: 0 up to
  /// round-off for crossings, up to the snap distance for snapped vertices.
  VertexData<double> cut_offset_;
  /// The tag of the sweep this move added to the swept-surface index, or -1 if none.
  std::int64_t move_sweep_ = -1;
  Vec3 move_rest_low_ = Vec3::Zero();  ///< bounds of move_rest_triangles_ (m), set by open_cut
  Vec3 move_rest_high_ = Vec3::Zero();
  TetData<Ancestry> ancestry_;
  std::vector<std::uint8_t> ancestor_codes_;
  std::vector<char> ancestor_presplit_;       ///< per original: given the generic split already
  std::vector<std::array<Vec3, 3>> surface_;  ///< every swept triangle, for inspection
  BladePose pose_;
  bool started_ = false;
  TetId point_tet_ = kInvalidId;
  std::vector<TetId> active_;
  CutStats stats_;
  std::vector<TetId> scratch_;
  /// keep_no_shards' walks: tetrahedra in a large piece, in a small region already looked
  /// at, and in the region being walked (sets kept between moves: cleared by a stamp).
  struct ShardWalks {
    StampedSet large;
    StampedSet checked;
    StampedSet inside;
  };
  ShardWalks shard_walks_;
};

}  // namespace incise
