#pragma once
// Internal forces of a deformable body attached to a TetMesh (mass-spring, FEM). A model keeps
// its data in attribute containers, so it follows every edit of the mesh without knowing who
// made it.

#include <span>
#include <string>

#include "incise/physics/block_sparse.hpp"
#include "incise/physics/dynamic_system.hpp"
#include "incise/physics/material_map.hpp"

namespace incise {

/// Forces one vertex at a time, for schemes that relax vertex by vertex (the seed's
/// hierarchical breadth-first RK4). Optional: ForceModel::vertex_forces().
class VertexForces {
 public:
  VertexForces() = default;
  VertexForces(const VertexForces&) = delete;
  VertexForces& operator=(const VertexForces&) = delete;
  virtual ~VertexForces() = default;

  /// Internal force on one vertex (N), its neighbours' states given by `neighbor`.
  [[nodiscard]] virtual Vec3 vertex_force(VertexId vertex, const Vec3& x, const Vec3& v,
                                          const NeighborState& neighbor) const = 0;
  /// The vertices whose state enters vertex_force(vertex): its neighbours in the model's graph.
  [[nodiscard]] virtual std::span<const VertexId> neighbors(VertexId vertex) const = 0;
};

/// The force's linearisation (stiffness K and damping D), for implicit schemes and static
/// solves. Optional: ForceModel::linearization().
class ForceLinearization {
 public:
  ForceLinearization() = default;
  ForceLinearization(const ForceLinearization&) = delete;
  ForceLinearization& operator=(const ForceLinearization&) = delete;
  virtual ~ForceLinearization() = default;

  /// Linearises the force about positions x (m) and velocities v (m/s): what the products and
  /// the assembly below then use, until the next call.
  virtual void prepare_linearization(std::span<const Vec3> x, std::span<const Vec3> v) = 0;
  /// The model's forces added to f, then prepare_linearization at the same state; models that
  /// share work between the two (the FEM's rotations) do both in one pass.
  virtual void add_forces_and_linearize(std::span<const Vec3> x, std::span<const Vec3> v,
                                        std::span<Vec3> f) = 0;
  /// y += (a K + b D) p, with K = -df/dx (N/m) and D = -df/dv (N s/m) of the last
  /// linearisation.
  virtual void add_linearized_product(double a, double b, std::span<const Vec3> p,
                                      std::span<Vec3> y) const = 0;
  /// Adds the diagonal 3x3 blocks of a K + b D, one per vertex (for preconditioning).
  virtual void add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const = 0;
  /// Writes a K + b D of the last linearisation into `matrix` (its pattern rebuilt when the
  /// mesh changed); false when the model offers products only.
  virtual bool assemble_linearization(double /*a*/, double /*b*/,
                                      BlockSparseMatrix& /*matrix*/) const {
    return false;
  }
};

/// A body's internal forces: the small core every model has (masses, forces, energy). What
/// only some schemes need is an optional capability a model may offer, so a new model starts
/// with the core and runs under the schemes that need nothing more (explicit Euler, RK4).
class ForceModel {
 public:
  ForceModel() = default;
  ForceModel(const ForceModel&) = delete;
  ForceModel& operator=(const ForceModel&) = delete;
  virtual ~ForceModel() = default;

  /// The model's name as scenes spell it ("mass-spring", "corotational-fem").
  [[nodiscard]] virtual std::string name() const = 0;
  /// Processes mesh edits since the last call; cheap when there were none.
  virtual void refresh() = 0;
  /// Total mass (kg), exact across edits (summed over elements).
  [[nodiscard]] virtual double total_mass() const = 0;
  /// Lumped masses (kg) per vertex.
  [[nodiscard]] virtual std::span<const double> masses() const = 0;
  /// Adds internal (elastic and internal damping) forces.
  virtual void add_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                          std::span<Vec3> f) const = 0;
  /// Elastic energy (J) at positions x (m).
  [[nodiscard]] virtual double elastic_energy(std::span<const Vec3> x) const = 0;
  /// Upper bound on the highest natural angular frequency at rest (rad/s), for step limits.
  [[nodiscard]] virtual double max_vertex_frequency() const = 0;

  /// The body's materials (a table and a material per tetrahedron), when the model keeps one.
  [[nodiscard]] virtual const MaterialMap* material_map() const { return nullptr; }

  /// Forces one vertex at a time, or null when the model does not offer them.
  [[nodiscard]] virtual const VertexForces* vertex_forces() const { return nullptr; }
  /// The force's linearisation for implicit schemes, or null when the model does not offer it.
  [[nodiscard]] virtual ForceLinearization* linearization() { return nullptr; }
};

}  // namespace incise
