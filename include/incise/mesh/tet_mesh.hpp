#pragma once
// TetMesh: the one mesh that changes. Rest positions (m), positively oriented tetrahedra,
// and adjacency (tet-tet across faces, vertex -> tets, unique edges, edge -> tets) that stays
// correct under every edit. Everything else (physics state, rest data, cut state) lives in
// attribute containers that observe the mesh and follow each edit; see attributes.hpp.

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/core/types.hpp"
#include "incise/mesh/edge_index.hpp"

namespace incise {

/// Local numbering inside one tetrahedron (v0, v1, v2, v3).
namespace tet_local {
/// Face i is opposite vertex i; listed counter-clockwise seen from outside a positive tet.
inline constexpr std::array<std::array<int, 3>, 4> kFaces = {
    {{{1, 2, 3}}, {{0, 3, 2}}, {{0, 1, 3}}, {{0, 2, 1}}}};
/// Edge k joins kEdges[k][0] and kEdges[k][1]; bit k of a cut-edge code refers to edge k.
inline constexpr std::array<std::array<int, 2>, 6> kEdges = {
    {{{0, 1}}, {{0, 2}}, {{0, 3}}, {{1, 2}}, {{1, 3}}, {{2, 3}}}};
}  // namespace tet_local

/// Neighbour value for a face that no other tetrahedron shares.
inline constexpr TetId kBoundaryFace = -1;
/// Neighbour value for a face shared by three or more tetrahedra (an invalid mesh).
inline constexpr TetId kNonManifoldFace = -2;

/// How a vertex came to be; attribute containers use it to fill in new values.
struct VertexOrigin {
  /// The ways a vertex is made.
  enum class Kind : std::uint8_t {
    kFresh,        ///< given a position directly (loaded, generated, add_vertex(position))
    kCombination,  ///< weighted combination of parent vertices (a point on an edge or face)
    kDuplicate,    ///< copy of one vertex, used to open a cut (parents[0] is the original)
  };
  Kind kind = Kind::kFresh;       ///< how it came to be
  std::uint8_t parent_count = 0;  ///< parents used (0 for a fresh vertex)
  /// The vertices it combines or copies.
  std::array<VertexId, 4> parents{kInvalidId, kInvalidId, kInvalidId, kInvalidId};
  std::array<double, 4> weights{0.0, 0.0, 0.0, 0.0};  ///< of the parents, summing to one
};

/// A new edge and, where it lies on an edge that existed before the edit (a piece of a split
/// edge, or the copy of an edge at a duplicated vertex), that parent and the length fraction
/// |new edge| / |parent edge| in rest coordinates.
struct EdgeOrigin {
  EdgeId edge = kInvalidId;    ///< the new edge
  EdgeId parent = kInvalidId;  ///< the edge it lies on, or kInvalidId
  double fraction = 0.0;       ///< |new edge| / |parent edge| at rest
};

class TetMesh;

/// Told of every edit of a TetMesh. Attribute containers implement this; so can caches.
/// Events arrive in the order the edit happens; ids in an event are valid at that moment.
class MeshObserver {
 public:
  MeshObserver() = default;
  MeshObserver(const MeshObserver&) = default;             ///< copyable
  MeshObserver& operator=(const MeshObserver&) = default;  ///< copyable
  virtual ~MeshObserver() = default;

  /// A vertex appended (a fresh one, a point on an edge or face, or a copy).
  virtual void on_vertex_added(const TetMesh& /*mesh*/, VertexId /*vertex*/,
                               const VertexOrigin& /*origin*/) {}
  /// A tetrahedron appended with no parent.
  virtual void on_tet_added(const TetMesh& /*mesh*/, TetId /*tet*/) {}
  /// `parent` was replaced by `children`; children[0] == parent (the slot is reused), the
  /// others were appended. `parent_vertices` are the parent's vertices before the edit.
  /// Observers still hold the parent's old value at `parent`.
  virtual void on_tet_replaced(const TetMesh& /*mesh*/, TetId /*parent*/,
                               std::span<const TetId> /*children*/,
                               const Tet& /*parent_vertices*/) {}
  /// `removed` (whose vertices were `removed_vertices`) is gone; the tetrahedron that was last
  /// (`moved_from`) now lives at `removed`. When removed == moved_from the last one was removed.
  virtual void on_tet_removed(const TetMesh& /*mesh*/, TetId /*removed*/, TetId /*moved_from*/,
                              const Tet& /*removed_vertices*/) {}
  /// A tetrahedron kept its id but now uses other vertices (duplicate_vertex moved it to the
  /// copy); `old_vertices` are those it used before.
  virtual void on_tet_reconnected(const TetMesh& /*mesh*/, TetId /*tet*/,
                                  const Tet& /*old_vertices*/) {}
  /// A tetrahedron kept its id (and its values) but one corner is now another vertex at
  /// another place (collapse_vertex): its rest shape changed. By default, as a reconnection.
  virtual void on_tet_reshaped(const TetMesh& mesh, TetId tet, const Tet& old_vertices) {
    on_tet_reconnected(mesh, tet, old_vertices);
  }
  /// `removed` is gone and its material belongs to `into` now (collapse_vertex: `into` grew
  /// over the space `removed` filled); `into` is its id before what follows: as for
  /// on_tet_removed, the last tetrahedron (`moved_from`) then takes the id `removed`. By
  /// default, as a removal.
  virtual void on_tet_absorbed(const TetMesh& mesh, TetId removed, TetId /*into*/, TetId moved_from,
                               const Tet& removed_vertices) {
    on_tet_removed(mesh, removed, moved_from, removed_vertices);
  }
  /// Edges appended by one edit, in id order. Edges that the same edit makes unused are still
  /// present (with no tetrahedra) until their on_edge_removed event follows.
  virtual void on_edges_created(const TetMesh& /*mesh*/, std::span<const EdgeOrigin> /*edges*/) {}
  /// `vertex` is about to move (relocate_vertex); the mesh and observers are still as before.
  virtual void on_vertex_relocating(const TetMesh& /*mesh*/, VertexId /*vertex*/) {}
  /// `vertex` now lies at a combination of other vertices (`origin`, as for a vertex added
  /// there; its old value may be among the parents): values that follow vertices are taken
  /// again as for a new vertex. Its tetrahedra are the same, their rest shapes are not.
  virtual void on_vertex_relocated(const TetMesh& /*mesh*/, VertexId /*vertex*/,
                                   const VertexOrigin& /*origin*/) {}
  /// Same swap-with-last convention as on_tet_removed.
  virtual void on_edge_removed(const TetMesh& /*mesh*/, EdgeId /*removed*/, EdgeId /*moved_from*/) {
  }
  /// A tetrahedron's material fraction changed (set_material_fraction).
  virtual void on_material_fraction_changed(const TetMesh& /*mesh*/, TetId /*tet*/) {}
  /// The observed mesh is being destroyed: forget it (do not unregister).
  virtual void on_mesh_destroyed() {}

  // ---- checkpoints -------------------------------------------------------------------------
  /// An observer with state writes it here; TetMesh::save_state calls every observer in the
  /// order they registered, after the mesh itself.
  virtual void save_state(StateWriter& /*out*/) const {}
  /// Reads back what save_state wrote, once the mesh is restored (caches may rebuild instead).
  virtual void load_state(StateReader& /*in*/) {}
};

/// A tetrahedral mesh with incrementally maintained adjacency.
class TetMesh {
 public:
  TetMesh() = default;
  /// Builds the mesh and its adjacency in bulk. Throws InputError for vertex ids out of range
  /// or a tetrahedron that repeats a vertex. Orientation is not checked here (see validate()).
  TetMesh(std::vector<Vec3> rest_positions, std::vector<Tet> tets);
  /// The same with a region label per tetrahedron (as many as tets; empty: all 0).
  TetMesh(std::vector<Vec3> rest_positions, std::vector<Tet> tets, std::vector<int> labels);

  /// Copies geometry and adjacency, not observers.
  TetMesh(const TetMesh& other);
  TetMesh& operator=(const TetMesh& other);  ///< copies geometry and adjacency, not observers
  /// Moves a mesh nobody observes yet (a reader's result into its place). The ownership
  /// rule: attributes and models attach to a mesh where it will stay; moving an observed
  /// mesh, or onto one, throws InternalError.
  TetMesh(TetMesh&& other);
  TetMesh& operator=(TetMesh&& other);  ///< as the move constructor
  ~TetMesh();

  // ---- sizes and geometry ----------------------------------------------------------------
  [[nodiscard]] std::size_t vertex_count() const { return rest_positions_.size(); }  ///< vertices
  [[nodiscard]] std::size_t tet_count() const { return tets_.size(); }               ///< tetrahedra
  [[nodiscard]] std::size_t edge_count() const { return edges_.size(); }             ///< edges

  /// A vertex's rest position (m, or the file's unit).
  [[nodiscard]] const Vec3& rest_position(VertexId vertex) const { return rest_positions_[vertex]; }
  /// Every vertex's rest position, by id.
  [[nodiscard]] std::span<const Vec3> rest_positions() const { return rest_positions_; }
  /// A tetrahedron's corners (vertex ids, positively oriented in a valid mesh).
  [[nodiscard]] const Tet& tet(TetId tet) const { return tets_[tet]; }
  [[nodiscard]] std::span<const Tet> tets() const { return tets_; }  ///< every tetrahedron, by id
  /// Region label of a tetrahedron (a file's physical group, subdomain or reference; 0 when
  /// the file had none). Children of a split keep their parent's label.
  [[nodiscard]] int tet_label(TetId tet) const { return tet_labels_[tet]; }
  [[nodiscard]] std::span<const int> tet_labels() const { return tet_labels_; }  ///< by id
  void set_tet_label(TetId tet, int label) { tet_labels_[tet] = label; }  ///< observers not told
  /// The share of a tetrahedron's rest volume that holds material, in [0, 1] (1 unless a
  /// cutter that keeps elements whole, such as XFEM's virtual elements, says otherwise). On the
  /// mesh, so any cutter can set it and every model sees it; children keep their parent's.
  [[nodiscard]] double material_fraction(TetId tet) const { return tet_fractions_[tet]; }
  /// Every tetrahedron's material fraction, by id.
  [[nodiscard]] std::span<const double> material_fractions() const { return tet_fractions_; }
  /// Throws InputError outside [0, 1]; observers are told (models reweigh the element).
  void set_material_fraction(TetId tet, double fraction);
  /// How a vertex came to be (fresh, a combination of parents, a copy).
  [[nodiscard]] const VertexOrigin& vertex_origin(VertexId vertex) const {
    return vertex_origins_[vertex];
  }

  // ---- adjacency --------------------------------------------------------------------------
  /// Neighbour across face i (opposite vertex i): a tet id, kBoundaryFace or kNonManifoldFace.
  [[nodiscard]] const std::array<TetId, 4>& tet_neighbors(TetId tet) const {
    return tet_neighbors_[tet];
  }
  /// Tetrahedra using a vertex, in no particular order.
  [[nodiscard]] std::span<const TetId> vertex_tets(VertexId vertex) const {
    return vertex_tets_[vertex];
  }
  /// The two vertices of an edge, smaller id first.
  [[nodiscard]] const std::array<VertexId, 2>& edge(EdgeId edge) const { return edges_[edge]; }
  /// Tetrahedra around an edge, in no particular order.
  [[nodiscard]] std::span<const TetId> edge_tets(EdgeId edge) const { return edge_tets_[edge]; }
  /// Edge ids of a tetrahedron, in tet_local::kEdges order.
  [[nodiscard]] const std::array<EdgeId, 6>& tet_edges(TetId tet) const { return tet_edges_[tet]; }
  /// The edge joining two vertices, or kInvalidId.
  [[nodiscard]] EdgeId find_edge(VertexId a, VertexId b) const;
  /// Local index (0-3) of a vertex in a tetrahedron, or -1.
  [[nodiscard]] int local_index(TetId tet, VertexId vertex) const;

  /// Incremented by every edit; caches compare it instead of keeping dirty flags.
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

  // ---- edits --------------------------------------------------------------------------------
  /// Appends a vertex at a rest position (m).
  VertexId add_vertex(const Vec3& rest_position);
  /// Appends a vertex at sum(weights[i] * rest_position(parents[i])); 1 to 4 parents,
  /// weights non-negative and summing to 1 (within 1e-9), else throws InputError.
  VertexId add_vertex(std::span<const VertexId> parents, std::span<const double> weights);
  /// Appends a copy of `original` and makes each tetrahedron in `tets_to_move` use the copy
  /// instead; faces between moved and unmoved tetrahedra become boundary. Throws InputError if
  /// a listed tetrahedron does not use `original`.
  VertexId duplicate_vertex(VertexId original, std::span<const TetId> tets_to_move);
  /// Appends a tetrahedron with no parent, in region `label`.
  TetId add_tet(const Tet& tet, int label = 0);
  /// Replaces `parent` by `children` (at least one): the first child takes the parent's id,
  /// the others are appended. Returns the children's ids.
  std::vector<TetId> replace_tet(TetId parent, std::span<const Tet> children);
  /// Removes a tetrahedron; the last one takes its id (observers are told).
  void remove_tet(TetId tet);
  /// Moves a vertex to sum(weights[i] * rest_position(parents[i])) (the vertex may be among
  /// its parents), keeping its tetrahedra: values that follow vertices (positions, velocities)
  /// are interpolated again from the parents, as for a new vertex. The caller keeps every
  /// tetrahedron around it positive. The cutter slides a vertex on the blade line along with
  /// the blade instead of leaving one behind every frame.
  void relocate_vertex(VertexId vertex, std::span<const VertexId> parents,
                       std::span<const double> weights);
  /// Collapses `vertex` onto `target` (an edge collapse): each tetrahedron using both is
  /// removed and absorbed (on_tet_absorbed) by its neighbour across the face opposite
  /// `target`; every other tetrahedron using `vertex` uses `target` instead
  /// (on_tet_reshaped). `vertex` is left with no tetrahedra (an unreferenced vertex). Throws
  /// InputError, changing nothing, unless (vertex, target) is an edge, every removed
  /// tetrahedron has such a neighbour that is kept, and the result repeats no tetrahedron and
  /// puts no face on three (the link condition). The caller keeps every reshaped tetrahedron
  /// positive and the region they fill the same. The subdivision cutter collapses a blade-line
  /// vertex the blade has left behind onto the crossing next to it.
  void collapse_vertex(VertexId vertex, VertexId target);
  /// Moves a vertex's rest position (m), e.g. snapping; adjacency is unchanged.
  void set_rest_position(VertexId vertex, const Vec3& rest_position);

  // ---- observers ------------------------------------------------------------------------
  /// Tells `observer` of every edit from now on (it must unregister before it dies).
  void add_observer(MeshObserver* observer);
  void remove_observer(MeshObserver* observer);  ///< no longer tells it
  /// Puts `new_observer` in the old one's place in the order of notification (a moved
  /// attribute container).
  void replace_observer(MeshObserver* old_observer, MeshObserver* new_observer);

  // ---- checkpoints -------------------------------------------------------------------------
  /// Writes everything: geometry, labels, origins, adjacency exactly as maintained (so later
  /// edits iterate in the same order), the revision, then each observer's state.
  void save_state(StateWriter& out) const;
  /// Replaces this mesh by a saved one and restores its observers, which must be the same
  /// kinds registered in the same order as when it was saved (checked).
  void load_state(StateReader& in);

  // ---- self-check -------------------------------------------------------------------------
  /// Rebuilds adjacency from scratch (the bulk algorithm) and compares it with the
  /// incrementally maintained one as sets. Returns an empty string when they agree, else a
  /// description of the first difference. For tests and debug assertions.
  [[nodiscard]] std::string compare_with_rebuilt_adjacency() const;

 private:
  void check_tet_ids(const Tet& tet) const;
  /// `mesh`, or InternalError when something observes it (the ownership rule).
  static TetMesh& unobserved(TetMesh& mesh);
  void attach(TetId tet);
  void detach(TetId tet);
  /// Takes `tet` off its vertices' and edges' lists (edges left with none are noted for
  /// finish_edit); its vertices, edge ids and neighbours stay as they were.
  void leave_lists(TetId tet);
  /// Puts `with` at local corner `at` of a tetrahedron that left its lists, and puts it back on
  /// them: its edges through that corner are found or made, the others kept. Faces untouched.
  void move_corner(TetId tet, int at, VertexId with);
  /// Drops a detached tetrahedron: the last one takes its id. Returns the id that moved.
  TetId erase_detached(TetId tet);
  void update_face(VertexId a, VertexId b, VertexId c);
  EdgeId find_or_create_edge(VertexId a, VertexId b);
  EdgeOrigin edge_parent(EdgeId edge) const;
  void append_vertex(const Vec3& rest_position, const VertexOrigin& origin);
  /// Checks parents and weights and returns the origin and `position` they give.
  VertexOrigin combination(const char* operation, std::span<const VertexId> parents,
                           std::span<const double> weights, Vec3& position) const;
  /// Emits edge events and drops unused edges at the end of an edit.
  void finish_edit();
  void build_adjacency();
  /// Capacity for the edits to come in every array (see core/growth.hpp).
  void reserve_all_for_edits();

  std::vector<Vec3> rest_positions_;
  std::vector<VertexOrigin> vertex_origins_;
  std::vector<Tet> tets_;
  std::vector<int> tet_labels_;
  std::vector<double> tet_fractions_;
  std::vector<std::array<TetId, 4>> tet_neighbors_;
  std::vector<std::array<EdgeId, 6>> tet_edges_;
  std::vector<std::vector<TetId>> vertex_tets_;
  std::vector<std::array<VertexId, 2>> edges_;
  std::vector<std::vector<TetId>> edge_tets_;
  EdgeIndex edge_index_;
  std::uint64_t revision_ = 0;

  // Per-edit bookkeeping: edges appended and edges left without tetrahedra.
  std::vector<EdgeId> edit_created_edges_;
  std::vector<EdgeId> edit_unused_edges_;

  std::vector<MeshObserver*> observers_;
};

/// Signed volume (m^3) of four points: det[b - a, c - a, d - a] / 6; positive for a
/// positively oriented tetrahedron. Floating point: use predicates.hpp for exact signs.
[[nodiscard]] double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
[[nodiscard]] double signed_volume(const TetMesh& mesh, TetId tet);
/// Barycentric coordinates of p in the tetrahedron (a, b, c, d) (floating point; they sum to 1
/// and are all in [0, 1] for a point inside).
[[nodiscard]] std::array<double, 4> barycentric_coordinates(const Vec3& p, const Vec3& a,
                                                            const Vec3& b, const Vec3& c,
                                                            const Vec3& d);
/// One key per undirected edge: the smaller vertex id in the high 32 bits, the larger below.
[[nodiscard]] std::uint64_t edge_key(VertexId a, VertexId b);
/// Rest positions (m) of a tetrahedron's four corners, in its order.
[[nodiscard]] std::array<Vec3, 4> rest_corners(const TetMesh& mesh, TetId tet);
/// Sum of signed tetrahedron volumes (m^3).
[[nodiscard]] double total_volume(const TetMesh& mesh);

/// Axis-aligned bounds of the rest positions, {low, high} (m); both zero for an empty mesh.
[[nodiscard]] std::pair<Vec3, Vec3> bounding_box(const TetMesh& mesh);

}  // namespace incise
