#pragma once
// Semi-progressive XFEM cutting in a mesh that changes (Gutierrez & Ramos, sections 3.1, 3.3
// and 3.5). The blade's swept surface between consecutive poses (the collision quad, cut into
// pieces no longer than quad_length) is tested against the edges of the tetrahedra near it
// (a uniform grid over their rest bounds, so the cost does not grow with the mesh); each edge
// remembers how often it was crossed and where. A tetrahedron splits once the edges crossed an
// odd number of times are exactly those between two groups of its corners (the seed's L1-L3
// lists end in a full crossing); until then it is the cut's front. It splits into two virtual
// elements over its unchanged rest tetrahedron (replace_tet: the first keeps its id), each
// weighted by its exact material fraction (TetMesh::set_material_fraction, so any model
// reweighs it). Far-side corners are vertex copies (duplicate_vertex), one per vertex, shared
// by every split tetrahedron around it, so a long cut separates the body.
//
// Exact decisions: crossings and touches come from exact orientation predicates (CGAL). A
// vertex the swept surface passes through exactly belongs to the surface's negative side, so
// cuts through vertices, along edges and in face planes split consistently; a tetrahedron left
// with no material on one side (its corners there all on the surface) keeps one element, the
// other is never created. An edge crossed twice (tremor: the blade went back over it) counts
// as not crossed, so tremor never splits a tetrahedron.
//
// The front stays closed (section 3.5): the two ends of every crossed edge that a front
// tetrahedron holds are tied, i.e. split elements use the vertex itself instead of its copy;
// once no front holds them any more the copy is made and those elements move to it. A tie is
// released once and never made again. A tetrahedron whose two elements would share three tied
// corners (a face: the mesh would not be manifold) waits until the ties release.
//
// The blade is given in the rest frame (as the subdivision cutter's in the engine). A
// tetrahedron is cut once: later crossings of a split tetrahedron are ignored (one Heaviside
// enrichment per element, as in the seed), and so are later crossings of its edges (only
// touches at a corner still count): a neighbour that splits later then cuts the face they
// share along the same segment, so the cut surface has no crack or overlap there (tremor and
// re-entry would otherwise change an edge's parity between the two splits).

#include <cstdint>
#include <memory>
#include <set>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/cut/blade.hpp"
#include "incise/cut/tet_grid.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/xfem/element_cut.hpp"

namespace incise {

/// How the XFEM cutter works (scene key `cutter` with `"type": "xfem"`).
struct XfemCutterOptions {
  /// m: the longest piece of swept surface tested at once (0: the mean edge length).
  double quad_length = 0.0;
  /// A virtual element never holds less than this share of its tetrahedron (the rest goes
  /// to its partner, so the material is conserved): a nearly empty element would make the
  /// system nearly singular. 0: exact fractions.
  double min_fraction = 1e-3;
};

/// What the XFEM cutter did, over every move unless said.
struct XfemCutterStats {
  std::size_t moves = 0;             ///< blade moves
  std::size_t quads = 0;             ///< swept pieces tested
  std::size_t elements_split = 0;    ///< rest tetrahedra split into virtual elements
  std::size_t copies = 0;            ///< vertex copies made (3 DOFs each)
  std::size_t fractions_raised = 0;  ///< elements given the minimum fraction
  std::size_t front_tets = 0;        ///< tetrahedra the cut reached without crossing them
  std::size_t tied_vertices = 0;     ///< vertices tied at the front now
  std::size_t waiting_tets = 0;      ///< crossed completely, waiting for ties to release
  std::size_t tremor_edges = 0;      ///< edges crossed an even number of times
  double min_fraction = 1.0;         ///< smallest fraction of any virtual element so far
  /// The physics' delay behind the blade, over every split: from the move that first reached
  /// a tetrahedron to the one that split it, in time (s) and in blade travel (m, midpoint).
  double delay_sum = 0.0;         ///< s, summed over the splits
  double delay_max = 0.0;         ///< s, the largest
  double delay_travel_sum = 0.0;  ///< m, summed over the splits
  double delay_travel_max = 0.0;  ///< m, the largest
  double cd_seconds = 0.0;        ///< last move: finding the crossings (s)
  double gc_seconds = 0.0;        ///< last move: splitting and tying (s)
};

/// The XFEM cutter (Gutierrez and Ramos): a tetrahedron the blade has crossed completely
/// becomes two virtual elements over its unchanged rest shape (semi-progressive cutting), with
/// vertex copies shared along the cut so that it separates the body.
class XfemCutter {
 public:
  /// Cuts `mesh` from now on; its tetrahedra now are the rest elements (none may be virtual
  /// yet). The mesh must outlive the cutter.
  explicit XfemCutter(TetMesh& mesh, XfemCutterOptions options = {});
  ~XfemCutter();
  XfemCutter(const XfemCutter&) = delete;
  XfemCutter& operator=(const XfemCutter&) = delete;

  /// Puts the blade down at `pose` without cutting (a new stroke).
  void start(const BladePose& pose);
  [[nodiscard]] bool started() const { return started_; }  ///< whether the blade was placed
  /// Moves the blade to `pose`, cutting what it sweeps.
  void move_to(const BladePose& pose);

  [[nodiscard]] const XfemCutterStats& stats() const { return stats_; }  ///< what it did
  /// The rest tetrahedra (the mesh's when the cutter was made).
  [[nodiscard]] std::size_t rest_tet_count() const { return rest_tets_.size(); }
  /// The rest tetrahedron an element integrates over.
  [[nodiscard]] TetId rest_tet_of(TetId element) const;
  /// The cut of a split rest tetrahedron, else nothing.
  [[nodiscard]] const std::optional<ElementCut>& cut_of(TetId rest_tet) const {
    return cuts_[static_cast<std::size_t>(rest_tet)];
  }
  /// The element of a split rest tetrahedron's side b when it has two (side a keeps the rest
  /// tetrahedron's id), else kInvalidId (whole, or only side b holds material: then the one
  /// element, at the rest tetrahedron's id, is side b's).
  [[nodiscard]] TetId second_element(TetId rest_tet) const {
    return second_element_[static_cast<std::size_t>(rest_tet)];
  }
  /// Whether a boundary face (vertex ids) was opened by the cut: its vertices, taken back to
  /// the originals they copy, are not a face of the body's boundary before the cut.
  [[nodiscard]] bool opened(const Triangle& face) const;
  /// Degrees of freedom the cut added (3 per vertex copy).
  [[nodiscard]] std::size_t dofs_added() const { return 3 * stats_.copies; }

  /// Checkpoints: the cut so far (edge crossings, splits, ties, statistics).
  void save_state(StateWriter& out) const;
  /// Restores what save_state() wrote, onto the same mesh restored from the same checkpoint.
  void load_state(StateReader& in);

 private:
  struct EdgeRecord {
    std::uint32_t crossings = 0;  ///< interior crossings
    double at = 0.5;              ///< last crossing, fraction from the smaller vertex id
    std::int8_t side_low = 0;     ///< side of the smaller-id end (-1, +1; 0 unknown)
    std::int8_t side_high = 0;
  };
  enum class TetState : std::uint8_t { kWhole, kFront, kWaiting, kSplit };

  void sweep(const BladePose& from, const BladePose& to, std::vector<TetId>& changed);
  /// Records the crossings of one swept quad; `changed` gets the tetrahedra it reached.
  void test_quad(const BladePose& from, const BladePose& to, std::vector<TetId>& changed);
  /// Records that edge (i, j) meets `triangle` (of the quad from -> to); true when it did.
  bool record_crossing(VertexId i, VertexId j, const std::array<Vec3, 3>& triangle);
  /// The cut the records make of a whole tetrahedron, if they cross it completely; `reached`
  /// says whether any record touches it.
  [[nodiscard]] std::optional<ElementCut> resolve(TetId rest_tet, bool& reached) const;
  [[nodiscard]] std::vector<std::uint8_t> tied_now() const;
  void release_ties(const std::vector<std::uint8_t>& tied);
  /// Splits a rest tetrahedron; false when it must wait (three tied corners).
  bool split(TetId rest_tet, const ElementCut& cut, const std::vector<std::uint8_t>& tied);
  [[nodiscard]] const EdgeRecord* record(VertexId a, VertexId b) const;
  /// Stops counting crossings of a split tetrahedron's edges.
  void freeze_edges(const Tet& rest_tet);
  /// The copy of `vertex` that the far side of a cut through it can use as the vertex's ghost:
  /// one joined (through the mesh, a few vertices away) to one of `far_corners`, the corners on
  /// that side; kInvalidId when no copy is (see split).
  [[nodiscard]] VertexId copy_joined_to(VertexId vertex,
                                        std::span<const VertexId> far_corners) const;

  TetMesh* mesh_;
  XfemCutterOptions options_;
  std::unique_ptr<TetGrid> grid_;
  std::vector<Tet> rest_tets_;                       ///< the tetrahedra as they were (original ids)
  std::set<std::array<VertexId, 3>> rest_boundary_;  ///< sorted vertex ids of boundary faces
  std::size_t rest_vertices_ = 0;                    ///< vertices before any copy
  std::vector<TetState> state_;                      ///< per rest tetrahedron
  std::vector<std::optional<ElementCut>> cuts_;
  std::vector<TetId> second_element_;    ///< per rest tetrahedron: element b's id, or -1
  std::vector<TetId> rest_of_appended_;  ///< per appended element (id - rest count)
  std::unordered_map<std::uint64_t, EdgeRecord> edges_;
  std::unordered_set<std::uint64_t> frozen_;  ///< edge_key of edges of split tetrahedra
  std::vector<std::uint8_t> touched_;         ///< per original vertex: on the swept surface
  std::vector<VertexId> copy_of_;             ///< per original vertex, or kInvalidId
  /// Per original vertex: copies made after copy_of_'s, for cuts whose far side is not joined
  /// to any earlier copy's (a blade crossing its own cut). Rebuilt from the mesh on load.
  std::unordered_map<VertexId, std::vector<VertexId>> more_copies_;
  /// Per original vertex without a copy yet: elements that use it in place of its copy.
  std::unordered_map<VertexId, std::vector<TetId>> tied_users_;
  std::vector<TetId> front_;  ///< rest tetrahedra in state kFront or kWaiting
  BladePose last_{};
  double travel_ = 0.0;  ///< m: the blade midpoint's travel so far
  /// Per rest tetrahedron: time (s) and travel (m) of the move that first reached it.
  std::vector<std::pair<double, double>> reached_at_;
  bool started_ = false;
  bool continues_ = false;  ///< the next quad starts where the last one ended (same stroke)
  XfemCutterStats stats_;
};

}  // namespace incise
