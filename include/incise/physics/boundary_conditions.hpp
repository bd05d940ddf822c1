#pragma once
// Boundary conditions that follow mesh edits: fixed vertices, prescribed displacements
// (the seed's displacement boundary conditions), point forces and gravity.

#include <span>
#include <vector>

#include "incise/mesh/attributes.hpp"

namespace incise {

/// A body's boundary conditions, per vertex, kept through the mesh's edits (attributes).
class BoundaryConditions {
 public:
  /// No vertex constrained, no force, no gravity; `mesh` must outlive the conditions.
  explicit BoundaryConditions(TetMesh& mesh);

  /// Keeps vertices at their rest positions.
  void fix(std::span<const VertexId> vertices);
  /// Moves vertices by displacement * min(1, t / ramp_time) from their rest positions
  /// (m, s; ramp_time 0 applies it at once).
  void prescribe_displacement(std::span<const VertexId> vertices, const Vec3& displacement,
                              double ramp_time);
  /// Spreads a total force (N) evenly over the vertices.
  void add_force(std::span<const VertexId> vertices, const Vec3& total_force);
  /// Adds a force (N) on one vertex (the engine's pushes add and take back theirs each step).
  void add_point_force(VertexId vertex, const Vec3& force) { point_force_[vertex] += force; }
  /// Gravitational acceleration (m/s^2).
  void set_gravity(const Vec3& gravity) { gravity_ = gravity; }
  /// Gravitational acceleration (m/s^2).
  [[nodiscard]] const Vec3& gravity() const { return gravity_; }

  /// Whether the vertex is fixed or moved by a prescribed displacement.
  [[nodiscard]] bool is_constrained(VertexId vertex) const { return group_[vertex] >= 0; }
  /// How many vertices are constrained.
  [[nodiscard]] std::size_t constrained_count() const;
  /// Position and velocity of a constrained vertex at time t.
  void prescribed_state(double t, VertexId vertex, const Vec3& rest, Vec3& x, Vec3& v) const;
  /// Point force (N) on a vertex (gravity not included).
  [[nodiscard]] const Vec3& point_force(VertexId vertex) const { return point_force_[vertex]; }

 private:
  struct Motion {
    Vec3 displacement = Vec3::Zero();  ///< m
    double ramp_time = 0.0;            ///< s
  };
  void assign(std::span<const VertexId> vertices, int group);

  TetMesh& mesh_;
  std::vector<Motion> motions_;
  /// Motion index per vertex, -1 when free. A vertex cut from parents that all share one
  /// motion gets it too; duplicates (cut faces) keep their original's.
  VertexData<std::int32_t> group_;
  /// New vertices get no point force, so duplicating a loaded vertex does not double the load.
  VertexData<Vec3> point_force_;
  Vec3 gravity_ = Vec3::Zero();
};

/// Vertices whose rest position lies in the closed box [low, high] (m).
[[nodiscard]] std::vector<VertexId> vertices_in_box(const TetMesh& mesh, const Vec3& low,
                                                    const Vec3& high);

}  // namespace incise
