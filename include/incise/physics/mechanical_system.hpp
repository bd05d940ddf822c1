#pragma once
// A deformable body ready to integrate: a force model, its boundary conditions, gravity and
// global damping, and its state (positions and velocities that follow mesh edits).

#include "incise/mesh/attributes.hpp"
#include "incise/physics/boundary_conditions.hpp"
#include "incise/physics/force_model.hpp"
#include "incise/physics/inversion_guard.hpp"

namespace incise {

/// Positions (m) and velocities (m/s) per vertex, interpolated onto vertices a cut creates.
struct SimulationState {
  /// At rest: x the mesh's rest positions, v zero.
  explicit SimulationState(TetMesh& mesh);
  VertexData<Vec3> x;  ///< positions (m)
  VertexData<Vec3> v;  ///< velocities (m/s)
  double time = 0.0;   ///< s
};

/// A body's global damping (scene key `damping`).
struct DampingParameters {
  /// Mass-proportional viscous damping in the force, f = -alpha m v (1/s).
  double viscous = 0.0;
  /// Velocity penalty applied exactly after each step, v <- v exp(-rate dt) (1/s): stable at
  /// any strength, unlike viscous damping in an explicit scheme (the seed's "penalty based
  /// damping", section 5.2).
  double penalty = 0.0;
};

/// A TetMesh body ready to step: a ForceModel, BoundaryConditions, gravity, damping and the
/// inversion guard, seen by the integrators as a DynamicSystem. It holds references: the mesh,
/// the model and the conditions must outlive it. One thread steps it.
class MechanicalSystem final : public DynamicSystem {
 public:
  /// `guard` (off unless its ratio is set) keeps tetrahedra right side out after each step.
  MechanicalSystem(TetMesh& mesh, ForceModel& model, BoundaryConditions& conditions,
                   const DampingParameters& damping = {},
                   const InversionGuardParameters& guard = {.min_volume_ratio = 0.0});

  void refresh() override { model_.refresh(); }
  void extend_vertex_values(std::vector<Vec3>& values) const override;
  [[nodiscard]] std::size_t vertex_count() const override { return mesh_.vertex_count(); }
  [[nodiscard]] std::span<const double> masses() const override { return model_.masses(); }
  void forces(double t, std::span<const Vec3> x, std::span<const Vec3> v,
              std::span<Vec3> f) override;
  Vec3 vertex_force(double t, VertexId vertex, const Vec3& x, const Vec3& v,
                    const NeighborState& neighbor) override;
  [[nodiscard]] std::span<const VertexId> neighbors(VertexId vertex) const override {
    return per_vertex().neighbors(vertex);
  }
  [[nodiscard]] bool is_constrained(VertexId vertex) const override {
    return conditions_.is_constrained(vertex);
  }
  void prescribed_state(double t, VertexId vertex, Vec3& x, Vec3& v) const override {
    conditions_.prescribed_state(t, vertex, mesh_.rest_position(vertex), x, v);
  }
  void prepare_linearization(double t, std::span<const Vec3> x, std::span<const Vec3> v) override;
  void forces_and_linearization(double t, std::span<const Vec3> x, std::span<const Vec3> v,
                                std::span<Vec3> f) override;
  void add_linearized_product(double a, double b, std::span<const Vec3> p,
                              std::span<Vec3> y) const override;
  void add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const override;
  bool assemble_linearization(double a, double b, BlockSparseMatrix& matrix) const override;
  [[nodiscard]] double potential_energy(double t, std::span<const Vec3> x) const override;
  void external_forces(double t, std::span<Vec3> f) const override;
  [[nodiscard]] double max_frequency() const override;
  void end_step(double dt, std::span<Vec3> v) override;
  void end_step(double dt, VertexId vertex, Vec3& v) override;
  void begin_step(double t, std::span<Vec3> x, std::span<Vec3> v) override;
  void finish_step(double t, std::span<Vec3> x, std::span<Vec3> v) override;

  /// Tetrahedra the inversion guard pushed back since the start (summed over steps), and the
  /// most it found in one step.
  [[nodiscard]] std::uint64_t guarded_tets() const { return guarded_tets_; }
  /// The most tetrahedra the guard pushed back in one step.
  [[nodiscard]] std::size_t guarded_tets_most() const { return guarded_tets_most_; }
  /// Vertices its fallback moved back towards the start of their step, summed over steps.
  [[nodiscard]] std::uint64_t backtracked_vertices() const { return backtracked_; }
  /// The most vertices the fallback moved back in one step.
  [[nodiscard]] std::size_t backtracked_vertices_most() const { return backtracked_most_; }
  /// The guard's parameters (a zero ratio when it is off).
  [[nodiscard]] const InversionGuardParameters& guard() const { return guard_; }
  /// An explicit step beyond its stability limit must show as divergence, not be pushed back.
  void turn_guard_off() { guard_.min_volume_ratio = 0.0; }

  /// The body's force model.
  [[nodiscard]] ForceModel& model() { return model_; }
  /// The body's boundary conditions.
  [[nodiscard]] BoundaryConditions& conditions() { return conditions_; }
  /// The body's mesh.
  [[nodiscard]] const TetMesh& mesh() const { return mesh_; }

 private:
  /// The model's optional capabilities; a clear error when the scheme needs one it lacks.
  [[nodiscard]] const VertexForces& per_vertex() const;
  [[nodiscard]] ForceLinearization& linearized() const;
  /// f = gravity, point forces and viscous damping (overwrites f).
  void external_and_damping_forces(std::span<const Vec3> v, std::span<Vec3> f) const;
  /// Adds what one call of the inversion guard did to the counts.
  void note(const InversionGuardOutcome& outcome);

  TetMesh& mesh_;
  ForceModel& model_;
  BoundaryConditions& conditions_;
  DampingParameters damping_;
  InversionGuardParameters guard_;
  std::vector<Vec3> step_start_;  ///< positions (m) as the step began, for the guard's fallback
  /// The mesh's revision at the end of the last step: an edit since (a cut's slid or collapsed
  /// vertex takes its deformed position from other vertices) is checked as the step begins.
  std::uint64_t revision_checked_ = ~std::uint64_t{0};
  std::uint64_t guarded_tets_ = 0;
  std::uint64_t backtracked_ = 0;
  std::size_t backtracked_most_ = 0;
  std::size_t guarded_tets_most_ = 0;
};

/// Puts constrained vertices at their prescribed state for time t.
void apply_constraints(DynamicSystem& system, double t, std::span<Vec3> x, std::span<Vec3> v);

}  // namespace incise
