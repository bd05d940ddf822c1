#pragma once
// Corotational linear FEM on a TetMesh (seed 003, section 3.1 and appendix B; Mueller and
// Gross 2004): linear tetrahedra whose rotation is taken out by polar decomposition, lumped
// masses, Rayleigh damping. Rest data, material fractions, masses and rotation warm starts live
// in the mesh's attribute containers, so the model follows cuts without knowing about them.
//
// Element loops run in parallel in two passes: per element into per-element results, then per
// vertex, gathering over the vertex's tetrahedra in the mesh's order. Each sum has a fixed
// order, so the output does not depend on the number of threads, nor on whether the model was
// built afresh or followed edits (a resumed run matches one that never stopped).
//
// After an edit the model updates only what the edit touched (the issue "An engine you can
// step and cut at any size"): the mesh's events mark vertices, and refresh() takes again the
// rest shapes of their tetrahedra, their rows of the matrix pattern, those tetrahedra's places
// in it, and their lumped masses.

#include <Eigen/Geometry>
#include <vector>

#include "incise/core/packed_rows.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/vertex_graph.hpp"
#include "incise/mesh/vertex_marks.hpp"
#include "incise/physics/block_sparse.hpp"
#include "incise/physics/corotational.hpp"
#include "incise/physics/force_model.hpp"
#include "incise/physics/frequency_rows.hpp"
#include "incise/physics/material.hpp"
#include "incise/physics/material_map.hpp"

namespace incise {

struct CorotatedBatch;

/// The corotational FEM's options beyond the material.
struct CorotationalFemParameters {
  /// Rayleigh damping D = alpha M + beta K: alpha (1/s) and beta (s).
  double rayleigh_mass = 0.0;
  double rayleigh_stiffness = 0.0;  ///< beta (s)
  /// Tangent used by implicit solvers (see corotational.hpp): warped is cheapest, projected
  /// converges quadratically in Newton's method.
  TangentKind tangent = TangentKind::kWarped;
  /// Assemble the stiffness matrix once per linearisation (products are then one sparse
  /// pass) rather than multiplying element by element; see BENCHMARKS.md for the comparison.
  bool assemble = true;
};

/// Per-element rest data kept in a TetData container.
struct FemElement {
  TetRestShape shape;  ///< rest volume and shape gradients
  bool valid = false;  ///< false until computed, or when the rest shape is degenerate
};

/// Corotational linear elasticity on linear tetrahedra (Mueller and Gross): per element the
/// rotation of the polar decomposition, the stress of the rotated linear strain, lumped
/// masses; it follows each mesh edit around the vertices the edit touched. Forces, products
/// and assembly run in parallel over elements or rows on the caller's TBB arena.
class CorotationalFemModel final : public ForceModel,
                                   public VertexForces,
                                   public ForceLinearization,
                                   public MeshObserver {
 public:
  /// Throws InputError naming the element if a tetrahedron is inverted or degenerate at rest.
  CorotationalFemModel(TetMesh& mesh, const Material& material,
                       const CorotationalFemParameters& parameters = {});
  /// A body of several materials: each element takes its own Lame parameters and density.
  CorotationalFemModel(TetMesh& mesh, const MaterialAssignment& materials,
                       const CorotationalFemParameters& parameters = {});
  ~CorotationalFemModel() override;

  [[nodiscard]] const VertexForces* vertex_forces() const override { return this; }
  [[nodiscard]] ForceLinearization* linearization() override { return this; }
  [[nodiscard]] std::string name() const override { return "corotational-fem"; }
  void refresh() override;
  [[nodiscard]] std::span<const double> masses() const override { return masses_.values(); }
  void add_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                  std::span<Vec3> f) const override;
  [[nodiscard]] Vec3 vertex_force(VertexId vertex, const Vec3& x, const Vec3& v,
                                  const NeighborState& neighbor) const override;
  [[nodiscard]] std::span<const VertexId> neighbors(VertexId vertex) const override;
  void prepare_linearization(std::span<const Vec3> x, std::span<const Vec3> v) override;
  /// Forces and the linearisation at the same state in one element pass (each rotation is
  /// computed once).
  void add_forces_and_linearize(std::span<const Vec3> x, std::span<const Vec3> v,
                                std::span<Vec3> f) override;
  void add_linearized_product(double a, double b, std::span<const Vec3> p,
                              std::span<Vec3> y) const override;
  void add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const override;
  bool assemble_linearization(double a, double b, BlockSparseMatrix& matrix) const override;
  [[nodiscard]] double elastic_energy(std::span<const Vec3> x) const override;
  [[nodiscard]] double max_vertex_frequency() const override;

  /// Weight in [0, 1] of an element's stiffness and mass (1 by default; children inherit it).
  void set_material_fraction(TetId tet, double fraction);
  /// An element's weight, as set_material_fraction gave it.
  [[nodiscard]] double material_fraction(TetId tet) const { return mesh_->material_fraction(tet); }
  [[nodiscard]] double total_mass() const override;
  /// The first material (the only one of a uniform body) and its Lame parameters.
  [[nodiscard]] const Material& material() const { return materials_.table().front(); }
  /// The first material's Lame parameters.
  [[nodiscard]] const LameParameters& lame() const { return lames_.front(); }
  /// Every element's material.
  [[nodiscard]] const MaterialMap& materials() const { return materials_; }
  [[nodiscard]] const MaterialMap* material_map() const override { return &materials_; }
  /// Lame parameters of an element's material.
  [[nodiscard]] const LameParameters& lame(TetId tet) const { return lames_[materials_.id(tet)]; }
  /// The options it was made with, as changed since.
  [[nodiscard]] const CorotationalFemParameters& parameters() const { return parameters_; }
  /// Chooses the tangent of the next linearisations.
  void set_tangent(TangentKind kind) { parameters_.tangent = kind; }
  /// Chooses between an assembled stiffness and element-by-element products.
  void set_assemble(bool assemble) { parameters_.assemble = assemble; }
  /// Time (s) spent assembling since the last linearisation (K, or a system matrix a solver
  /// asked for).
  [[nodiscard]] double last_assembly_seconds() const { return assembly_seconds_; }

  /// Vertices whose tetrahedra, rows or masses changed since the last refresh (diagnostics).
  [[nodiscard]] std::size_t pending_vertices() const { return marks_.size(); }

  // ---- following edits: marks_ collects the vertices; these change element data too ------
  void on_mesh_destroyed() override { mesh_ = nullptr; }
  /// A collapse changed the tetrahedron's rest shape: its element is computed again.
  void on_tet_reshaped(const TetMesh& mesh, TetId tet, const Tet& old_vertices) override;
  /// The rest shapes of the vertex's tetrahedra changed: taken again at the next refresh.
  void on_vertex_relocated(const TetMesh& mesh, VertexId vertex,
                           const VertexOrigin& origin) override;
  /// Its values live in attribute containers (restored on their own); the matrix pattern,
  /// element places and masses are built again from them.
  void load_state(StateReader& /*in*/) override { rebuild_all_ = true; }

 private:
  /// Everything from the mesh: at construction and after a restore.
  void rebuild_all();
  /// Only around the marked vertices.
  void update_marked();
  /// One vertex's row of the frequency bound, and the rows an edit changed.
  [[nodiscard]] double frequency_row(VertexId vertex) const;
  void update_frequency_rows();
  /// Takes the element's rest shape (and a new element's mass) again if it is not valid.
  void update_element(TetId tet);
  /// The element's 16 block places in the pattern.
  void update_slots(TetId tet);
  struct Incidence {
    TetId tet;
    int corner;
    bool operator==(const Incidence&) const = default;
  };
  /// Runs body(tet, corner) for each tetrahedron at the vertex, in the mesh's order.
  template <typename Body>
  void for_each_incidence(VertexId vertex, const Body& body) const;
  /// for_each_incidence of `row` (rows up to `last` are visited in order by the caller), with
  /// prefetch(tet) run kIncidencesAhead incidences before body reaches the element.
  template <typename Prefetch, typename Body>
  void for_each_incidence_ahead(std::size_t row, std::size_t last, const Prefetch& prefetch,
                                const Body& body) const;
  /// How far ahead for_each_incidence_ahead asks for an element's data (8-20 measured alike).
  static constexpr std::size_t kIncidencesAhead = 12;
  /// Asks the caches for every line `value` lies in (a hint: nothing is read).
  template <typename T>
  static void prefetch_lines(const T& value);
  /// The vertex's incidences from the mesh.
  void take_incidences(VertexId vertex, std::vector<Incidence>& row) const;
  [[nodiscard]] Corners corners(TetId tet, std::span<const Vec3> x) const;
  void element_forces(std::span<const Vec3> x, std::span<const Vec3> v, std::span<Vec3> f,
                      bool linearize) const;
  /// Runs the element kernel over the valid elements with material, four at a time, and
  /// take(batch, lane, tet) for each; skip(t) for the others.
  template <typename Skip, typename Take>
  void for_each_element_batch(std::span<const Vec3> x, const Skip& skip, const Take& take) const;
  /// Takes lane `lane` of a batch for element `tet`: its rotation; with `stress` its scaled
  /// stress (with damping from the velocities v); with `linearize` its tangent data.
  void take_batch_result(const CorotatedBatch& batch, int lane, TetId tet, std::span<const Vec3> v,
                         bool stress, bool linearize) const;
  /// Sizes the tangent data for the mesh's elements.
  void resize_linearization();
  /// Asserts that the last linearisation kept the warped tangent's rotations (matrix-free
  /// products and diagonals read them; a linearisation with assembly does not keep them).
  void expect_warped_rotations_kept() const;
  /// An element's tangent as the one-element functions take it.
  [[nodiscard]] CorotatedLinearization linearization_of(TetId tet) const;
  void assemble_linearization_matrix();
  /// Assembles K into stiffness_ if the last linearisation has not been yet.
  void ensure_assembled() const;
  /// out = scale K, assembled row by row from the last linearisation.
  void assemble_rows(std::span<Mat3> out, double scale) const;
  /// Runs body(tet, element) for every element with a valid rest shape, in parallel over
  /// blocks of consecutive elements (for loops that write only per-element data).
  template <typename Body>
  void for_each_valid_element_in_order(const Body& body) const;

  TetMesh* mesh_;
  MaterialMap materials_;
  std::vector<LameParameters> lames_;  ///< per material
  CorotationalFemParameters parameters_;
  TetData<FemElement> elements_;
  TetData<double> tet_mass_;  ///< kg, before the material fraction; split by volume on cuts
  /// Rotation of each element at the last force evaluation: the warm start of the next.
  mutable TetData<Eigen::Quaterniond> rotations_;
  VertexData<double> masses_;
  /// Per tet: the storage index of block (a, b) in stiffness_.
  TetData<std::array<std::uint32_t, 16>> slots_;

  static constexpr std::uint64_t kNoRevision = ~std::uint64_t{0};
  std::uint64_t topology_revision_ = kNoRevision;  ///< mesh revision refresh() last saw
  bool rebuild_all_ = true;
  VertexMarks marks_;                ///< the vertices edits touched since the last refresh
  std::vector<TetId> touched_tets_;  ///< refresh()'s scratch
  std::vector<std::vector<VertexId>>
      marked_columns_;  ///< refresh()'s scratch: each marked row's columns
  /// Built from the mesh when neighbors() is first asked after an edit (explicit traversals
  /// only; implicit schemes never ask).
  mutable VertexGraph graph_;
  mutable std::uint64_t graph_revision_ = kNoRevision;
  /// The frequency bound, kept row by row once an explicit scheme asked for it, and the rest
  /// tangent per material its rows read.
  mutable bool frequency_kept_ = false;
  mutable FrequencyRows frequency_;
  mutable std::vector<CorotatedLinearization> rest_linearizations_;

  // Written by the element loops (each element only by its own thread).
  mutable std::vector<CorotatedLinearization> linearization_;  ///< exact or projected tangent
  /// The warped tangent: R per element, kept only by a linearisation without assembly (what
  /// the matrix-free products read).
  mutable std::vector<Mat3> warped_rotations_;
  bool warped_rotations_kept_ = false;  ///< whether the last linearisation kept them
  /// R grad N_a per element (warped tangent: what its assembly reads).
  mutable std::vector<std::array<Vec3, 4>> rotated_gradients_;
  mutable std::vector<Mat3> scaled_stress_;  ///< -w V P per element (N m), gathered per vertex
  mutable BlockSparseMatrix stiffness_;
  /// Per vertex: its tetrahedra in the mesh's order and its corner in each (gathers read
  /// these contiguously; rows rewritten only for marked vertices).
  PackedRows<Incidence> incidences_;
  mutable bool assembled_ = false;
  mutable bool assembly_pending_ = false;
  mutable double assembly_seconds_ = 0.0;
};

}  // namespace incise
