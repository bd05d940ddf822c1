#pragma once
// Internal forces of a deformable body attached to a TetMesh (mass-spring, FEM). A model keeps
// its data in attribute containers, so it follows every edit of the mesh without knowing who
// made it.

#include <span>
#include <string>

#include "incise/physics/block_sparse.hpp"
#include "incise/physics/dynamic_system.hpp"

namespace incise {

class ForceModel {
 public:
  ForceModel() = default;
  ForceModel(const ForceModel&) = delete;
  ForceModel& operator=(const ForceModel&) = delete;
  virtual ~ForceModel() = default;

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
  /// Internal force on one vertex.
  [[nodiscard]] virtual Vec3 vertex_force(VertexId vertex, const Vec3& x, const Vec3& v,
                                          const NeighborState& neighbor) const = 0;
  [[nodiscard]] virtual std::span<const VertexId> neighbors(VertexId vertex) const = 0;
  virtual void prepare_linearization(std::span<const Vec3> x, std::span<const Vec3> v) = 0;
  /// add_forces then prepare_linearization at the same state; models that share work between
  /// the two (the FEM's rotations) do both in one pass.
  virtual void add_forces_and_linearize(std::span<const Vec3> x, std::span<const Vec3> v,
                                        std::span<Vec3> f) {
    add_forces(x, v, f);
    prepare_linearization(x, v);
  }
  virtual void add_linearized_product(double a, double b, std::span<const Vec3> p,
                                      std::span<Vec3> y) const = 0;
  virtual void add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const = 0;
  /// Writes a K + b D of the last linearisation into `matrix` (its pattern rebuilt when the
  /// mesh changed); false when the model offers products only.
  virtual bool assemble_linearization(double /*a*/, double /*b*/,
                                      BlockSparseMatrix& /*matrix*/) const {
    return false;
  }
  [[nodiscard]] virtual double elastic_energy(std::span<const Vec3> x) const = 0;
  /// Upper bound on the highest natural angular frequency at rest (rad/s), for step limits.
  [[nodiscard]] virtual double max_vertex_frequency() const = 0;
};

}  // namespace incise
