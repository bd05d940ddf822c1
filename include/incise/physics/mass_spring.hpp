#pragma once
// Mass-spring tissue after Bielser et al. (seed 000, section 5): a mass at every vertex, a
// damped spring on every tetrahedron edge. Springs alone do not resist a tetrahedron turning
// inside out (a corner can pass through the opposite face with every edge at its length), so
// each tetrahedron also keeps its volume: Teschner et al.'s F_V (the planning seed), energy
// kappa V0 ((V - V0) / V0)^2 / 2 with kappa a share of the tetrahedron's Young's modulus.
// All data lives in attribute containers of the mesh, and the model updates only what an edit
// touched.

#include <array>
#include <utility>
#include <vector>

#include "incise/core/packed_rows.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/vertex_graph.hpp"
#include "incise/mesh/vertex_marks.hpp"
#include "incise/physics/force_model.hpp"
#include "incise/physics/frequency_rows.hpp"
#include "incise/physics/material.hpp"
#include "incise/physics/material_map.hpp"

namespace incise {

/// The mass-spring model's options beyond the material (scene keys under `model`).
struct MassSpringParameters {
  /// Damping ratio of each spring: c = ratio * 2 sqrt(k m_reduced) (dimensionless).
  double spring_damping_ratio = 0.1;
  /// Springs rest at (1 - prestrain) times their initial length, so the tissue is under
  /// tension and a cut opens (dimensionless, in [0, 1)).
  double prestrain = 0.0;
  /// kappa of each tetrahedron's volume term as a share of its Young's modulus
  /// (dimensionless; 0: springs only, as the seed, whose elements can turn inside out). Its
  /// rest volume is the one its springs rest at: (1 - prestrain)^3 times its initial volume.
  /// 0.1 keeps the default scene right side out (46 of 936 inside out with springs only).
  double volume_stiffness = 0.1;
};

/// d V / d x_k of a tetrahedron's signed volume V = (x1 - x0) . ((x2 - x0) x (x3 - x0)) / 6
/// (m^2): a third of each face's area times its inward normal, for the corner opposite it.
[[nodiscard]] std::array<Vec3, 4> volume_gradient(const std::array<Vec3, 4>& x);

/// A damped linear spring.
struct Spring {
  double rest_length = 0.0;  ///< m
  double stiffness = 0.0;    ///< N/m
  double damping = 0.0;      ///< N s/m
};

/// The seed's tissue (Bielser et al.): lumped masses and a damped spring on every mesh edge
/// (van Gelder's stiffness from the material), with an optional volume term per tetrahedron;
/// it follows each mesh edit around the vertices the edit touched. Forces run in parallel on
/// the caller's TBB arena.
class MassSpringModel final : public ForceModel,
                              public VertexForces,
                              public ForceLinearization,
                              public MeshObserver {
 public:
  /// A body of one material; `mesh` must outlive the model.
  MassSpringModel(TetMesh& mesh, const Material& material, const MassSpringParameters& parameters);
  /// A body of several materials: each tetrahedron's density gives its mass and its Young's
  /// modulus its share of the springs along its edges.
  MassSpringModel(TetMesh& mesh, const MaterialAssignment& materials,
                  const MassSpringParameters& parameters);
  ~MassSpringModel() override;

  [[nodiscard]] const VertexForces* vertex_forces() const override { return this; }
  [[nodiscard]] ForceLinearization* linearization() override { return this; }
  [[nodiscard]] std::string name() const override { return "mass-spring"; }
  void refresh() override;
  [[nodiscard]] std::span<const double> masses() const override { return masses_.values(); }
  void add_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                  std::span<Vec3> f) const override;
  [[nodiscard]] Vec3 vertex_force(VertexId vertex, const Vec3& x, const Vec3& v,
                                  const NeighborState& neighbor) const override;
  [[nodiscard]] std::span<const VertexId> neighbors(VertexId vertex) const override;
  void prepare_linearization(std::span<const Vec3> x, std::span<const Vec3> v) override;
  void add_forces_and_linearize(std::span<const Vec3> x, std::span<const Vec3> v,
                                std::span<Vec3> f) override {
    add_forces(x, v, f);
    prepare_linearization(x, v);
  }
  void add_linearized_product(double a, double b, std::span<const Vec3> p,
                              std::span<Vec3> y) const override;
  void add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const override;
  [[nodiscard]] double elastic_energy(std::span<const Vec3> x) const override;
  [[nodiscard]] double max_vertex_frequency() const override;

  /// The spring on a mesh edge.
  [[nodiscard]] const Spring& spring(EdgeId edge) const { return springs_[edge]; }
  [[nodiscard]] double total_mass() const override;
  /// The first material (the only one of a uniform body).
  [[nodiscard]] const Material& material() const { return materials_.table().front(); }
  /// Every tetrahedron's material.
  [[nodiscard]] const MaterialMap& materials() const { return materials_; }
  [[nodiscard]] const MaterialMap* material_map() const override { return &materials_; }

  // MeshObserver (marks_ collects the vertices whose mass or springs an edit changed): a
  // tetrahedron added afresh gets its mass here.
  void on_tet_added(const TetMesh& mesh, TetId tet) override;
  void on_mesh_destroyed() override { mesh_ = nullptr; }
  /// Its values live in attribute containers (restored on their own); springs and masses are
  /// recomputed from them.
  void load_state(StateReader& in) override;

 private:
  void rebuild_adjacency();
  /// The marked vertices' rows of neighbours_ and edges_at_, from their tetrahedra's edges.
  void update_adjacency();
  /// One vertex's row of the frequency bound, and the rows an edit changed.
  [[nodiscard]] double frequency_row(VertexId vertex) const;
  void update_frequency_rows();
  /// Spring force on vertex a from the spring to b (the force on b is its negative).
  [[nodiscard]] Vec3 spring_force(const Spring& spring, const Vec3& xa, const Vec3& va,
                                  const Vec3& xb, const Vec3& vb) const;
  /// A tetrahedron's volume stiffness kappa (Pa, weighted by its material fraction) and rest
  /// volume V0 (m^3), from the mesh (volume_terms_ holds them).
  [[nodiscard]] std::pair<double, double> volume_term(TetId tet) const;
  /// The volume forces (N) on the corners of a tetrahedron at `x`.
  [[nodiscard]] std::array<Vec3, 4> volume_forces(TetId tet, const std::array<Vec3, 4>& x) const;

  TetMesh* mesh_;
  MaterialMap materials_;
  MassSpringParameters parameters_;
  /// Mass of each tetrahedron (kg): density times rest volume, split among children in
  /// proportion to their volumes so the total never drifts.
  TetData<double> tet_mass_;
  VertexData<double> masses_;  ///< lumped: a quarter of each adjacent tetrahedron's mass
  EdgeData<Spring> springs_;
  /// Per tetrahedron: kappa (Pa) and rest volume V0 (m^3) of its volume term, refreshed with
  /// the springs around the vertices an edit touched.
  TetData<std::pair<double, double>> volume_terms_;

  VertexMarks marks_;  ///< the vertices edits touched since the last refresh
  std::uint64_t adjacency_revision_ = ~std::uint64_t{0};  ///< mesh revision refresh() last saw
  bool rebuild_adjacency_ = true;
  /// Per vertex, in edge order: its neighbours and the edges to them (rows rewritten only for
  /// marked vertices after an edit).
  PackedRows<VertexId> neighbours_;
  PackedRows<EdgeId> edges_at_;
  /// A tetrahedron at a vertex, for the per-vertex volume force: which corner the vertex is
  /// and where its other three corners sit in the vertex's row of neighbours_ (so their
  /// states, read once for the springs, need no search).
  struct TetCorners {
    TetId tet = kInvalidId;
    std::uint8_t own = 0;
    std::array<std::uint32_t, 4> slot{};  ///< per local corner (own's unused)
    bool operator==(const TetCorners&) const = default;
  };
  /// Per vertex (only with a volume term): its tetrahedra, rewritten with neighbours_.
  PackedRows<TetCorners> tet_corners_;
  /// tet_corners_'s row of vertex v, from its tetrahedra and its row of neighbours_.
  void set_tet_corners(VertexId v);
  /// The Gershgorin bound on the squared frequencies, row by row: explicit schemes ask for it
  /// every step.
  FrequencyRows frequency_;
  // Linearisation: per-edge stiffness and damping blocks.
  std::vector<Mat3> stiffness_blocks_;
  std::vector<Mat3> damping_blocks_;
  /// Per tetrahedron: kappa / V0 (Pa/m^3) and the volume gradient: the Gauss-Newton part of
  /// the volume term's Hessian, kappa / V0 g g^T (positive semi-definite).
  std::vector<double> volume_coefficients_;
  std::vector<std::array<Vec3, 4>> volume_gradients_;
};

}  // namespace incise
