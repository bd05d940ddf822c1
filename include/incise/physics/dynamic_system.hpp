#pragma once
// The integrators' view of a simulated body: M a = f(t, x, v) per vertex, with some vertices'
// motion prescribed. Positions in m, velocities in m/s, forces in N, masses in kg, time in s.

#include <functional>
#include <span>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/physics/block_sparse.hpp"

namespace incise {

/// Reads the current state (x, v) of another vertex during a per-vertex force evaluation.
using NeighborState = std::function<void(VertexId vertex, Vec3& position, Vec3& velocity)>;

/// What an integrator steps: masses, forces, prescribed vertices, the force's linearisation
/// and hooks around each step. MechanicalSystem is the one for a TetMesh body.
class DynamicSystem {
 public:
  DynamicSystem() = default;
  DynamicSystem(const DynamicSystem&) = delete;
  DynamicSystem& operator=(const DynamicSystem&) = delete;
  virtual ~DynamicSystem() = default;

  /// Brings internal data up to date after mesh edits (cheap when nothing changed).
  virtual void refresh() {}
  /// Extends per-vertex values (a solver's earlier solutions) onto vertices added since they
  /// were taken (those at values.size() and beyond), as positions are: a vertex on an edge or
  /// face takes its parents' weighted values, a copy made by a cut its original's. Without a
  /// mesh to ask, new vertices get zero.
  virtual void extend_vertex_values(std::vector<Vec3>& values) const {
    values.resize(vertex_count(), Vec3::Zero());
  }
  /// The number of vertices (the length of every state span).
  [[nodiscard]] virtual std::size_t vertex_count() const = 0;
  /// Lumped masses (kg).
  [[nodiscard]] virtual std::span<const double> masses() const = 0;

  /// Total force on every vertex (internal, external, damping) at time t.
  virtual void forces(double t, std::span<const Vec3> x, std::span<const Vec3> v,
                      std::span<Vec3> f) = 0;
  /// Total force on one vertex, the others read through `neighbor`.
  virtual Vec3 vertex_force(double t, VertexId vertex, const Vec3& x, const Vec3& v,
                            const NeighborState& neighbor) = 0;
  /// Vertices whose state enters vertex_force(vertex) (graph neighbours, for traversals).
  [[nodiscard]] virtual std::span<const VertexId> neighbors(VertexId vertex) const = 0;

  /// Whether the vertex's motion is prescribed; then prescribed_state gives it.
  [[nodiscard]] virtual bool is_constrained(VertexId vertex) const = 0;
  /// The prescribed position (m) and velocity (m/s) of a constrained vertex at time t (s).
  virtual void prescribed_state(double t, VertexId vertex, Vec3& x, Vec3& v) const = 0;

  /// Linearisation of the force about (x, v): prepare once, then y += a K p + b D p with
  /// K = -df/dx and D = -df/dv (symmetric positive semi-definite approximations).
  virtual void prepare_linearization(double t, std::span<const Vec3> x,
                                     std::span<const Vec3> v) = 0;
  /// y += (a K + b D) p for the last prepare_linearization.
  virtual void add_linearized_product(double a, double b, std::span<const Vec3> p,
                                      std::span<Vec3> y) const = 0;
  /// forces() then prepare_linearization() at the same state, in one pass where the system
  /// can share the work.
  virtual void forces_and_linearization(double t, std::span<const Vec3> x, std::span<const Vec3> v,
                                        std::span<Vec3> f) {
    forces(t, x, v, f);
    prepare_linearization(t, x, v);
  }
  /// Adds the diagonal 3x3 blocks of a K + b D (for preconditioning).
  virtual void add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const = 0;
  /// Writes a K + b D into `matrix` (pattern over the mesh's edges); false when the system
  /// offers products only (then direct solvers and incomplete factorisations are unavailable).
  virtual bool assemble_linearization(double /*a*/, double /*b*/,
                                      BlockSparseMatrix& /*matrix*/) const {
    return false;
  }

  /// Adds the external loads (gravity, point forces; N) to f: the scale of a static residual.
  virtual void external_forces(double /*t*/, std::span<Vec3> /*f*/) const {}
  /// Potential energy (J): elastic plus that of conservative external loads.
  [[nodiscard]] virtual double potential_energy(double t, std::span<const Vec3> x) const = 0;
  /// Upper estimate of the highest natural angular frequency (rad/s), for step-size limits.
  [[nodiscard]] virtual double max_frequency() const = 0;
  /// Called by integrators after each step of length dt on the velocities of the vertices they
  /// advanced (e.g. to apply velocity-penalty damping); does nothing by default.
  virtual void end_step(double /*dt*/, std::span<Vec3> /*v*/) {}
  /// The same for one vertex, from schemes that advance vertex by vertex.
  virtual void end_step(double /*dt*/, VertexId /*vertex*/, Vec3& /*v*/) {}
  /// Called by integrators as a step starts, after refresh(), with every vertex's state (which
  /// it may correct after mesh edits).
  virtual void begin_step(double /*t*/, std::span<Vec3> /*x*/, std::span<Vec3> /*v*/) {}
  /// Called by integrators once a whole step has ended at time t, with every vertex's state:
  /// the last word on it (e.g. tetrahedra pushed back right side out); nothing by default.
  virtual void finish_step(double /*t*/, std::span<Vec3> /*x*/, std::span<Vec3> /*v*/) {}
};

/// Kinetic energy (J) of velocities v with masses m.
[[nodiscard]] double kinetic_energy(std::span<const double> masses, std::span<const Vec3> v);

}  // namespace incise
