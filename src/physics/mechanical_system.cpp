#include "incise/physics/mechanical_system.hpp"

#include <algorithm>
#include <cmath>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"

namespace incise {

double kinetic_energy(std::span<const double> masses, std::span<const Vec3> v) {
  double energy = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    energy += 0.5 * masses[i] * v[i].squaredNorm();
  }
  return energy;
}

SimulationState::SimulationState(TetMesh& mesh)
    : x(mesh, Vec3::Zero(), VertexRule::kInterpolate),
      v(mesh, Vec3::Zero(), VertexRule::kInterpolate) {
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    x[static_cast<VertexId>(i)] = mesh.rest_position(static_cast<VertexId>(i));
  }
  // A fresh vertex starts at its rest position; combinations are interpolated by the rule.
  x.set_hook([](VertexData<Vec3>& positions, VertexId vertex, const VertexOrigin& origin) {
    if (origin.kind == VertexOrigin::Kind::kFresh) {
      positions[vertex] = positions.mesh()->rest_position(vertex);
    }
  });
}

MechanicalSystem::MechanicalSystem(TetMesh& mesh, ForceModel& model, BoundaryConditions& conditions,
                                   const DampingParameters& damping,
                                   const InversionGuardParameters& guard)
    : mesh_(mesh), model_(model), conditions_(conditions), damping_(damping), guard_(guard) {
  if (!(damping_.viscous >= 0.0) || !(damping_.penalty >= 0.0) ||
      !std::isfinite(damping_.viscous) || !std::isfinite(damping_.penalty)) {
    throw InputError("damping rates must be non-negative (1/s)");
  }
  if (!(guard_.min_volume_ratio >= 0.0 && guard_.min_volume_ratio < 1.0) || guard_.max_passes < 1) {
    throw InputError("the inversion guard's volume share must be in [0, 1) and it needs a pass");
  }
}

const VertexForces& MechanicalSystem::per_vertex() const {
  const VertexForces* forces = model_.vertex_forces();
  if (forces == nullptr) {
    throw InputError("model '" + model_.name() +
                     "' gives no per-vertex forces, which vertex-by-vertex relaxation "
                     "(rk4-hierarchical) needs: choose rk4, symplectic-euler or backward-euler");
  }
  return *forces;
}

ForceLinearization& MechanicalSystem::linearized() const {
  ForceLinearization* linearization = model_.linearization();
  if (linearization == nullptr) {
    throw InputError("model '" + model_.name() +
                     "' gives no linearisation, which implicit and static solves "
                     "(backward-euler, static) need: choose an explicit integrator");
  }
  return *linearization;
}

void MechanicalSystem::external_and_damping_forces(std::span<const Vec3> v,
                                                   std::span<Vec3> f) const {
  const auto masses = model_.masses();
  const Vec3& gravity = conditions_.gravity();
  for (std::size_t i = 0; i < f.size(); ++i) {
    const auto vertex = static_cast<VertexId>(i);
    f[i] = masses[i] * (gravity - damping_.viscous * v[i]) + conditions_.point_force(vertex);
  }
}

void MechanicalSystem::forces(double, std::span<const Vec3> x, std::span<const Vec3> v,
                              std::span<Vec3> f) {
  external_and_damping_forces(v, f);
  model_.add_forces(x, v, f);
}

void MechanicalSystem::forces_and_linearization(double, std::span<const Vec3> x,
                                                std::span<const Vec3> v, std::span<Vec3> f) {
  external_and_damping_forces(v, f);
  linearized().add_forces_and_linearize(x, v, f);
}

Vec3 MechanicalSystem::vertex_force(double, VertexId vertex, const Vec3& x, const Vec3& v,
                                    const NeighborState& neighbor) {
  const double mass = model_.masses()[static_cast<std::size_t>(vertex)];
  return mass * (conditions_.gravity() - damping_.viscous * v) + conditions_.point_force(vertex) +
         per_vertex().vertex_force(vertex, x, v, neighbor);
}

void MechanicalSystem::prepare_linearization(double, std::span<const Vec3> x,
                                             std::span<const Vec3> v) {
  linearized().prepare_linearization(x, v);
}

void MechanicalSystem::add_linearized_product(double a, double b, std::span<const Vec3> p,
                                              std::span<Vec3> y) const {
  linearized().add_linearized_product(a, b, p, y);
  if (damping_.viscous > 0.0 && b != 0.0) {
    const auto masses = model_.masses();
    for (std::size_t i = 0; i < p.size(); ++i) {
      y[i] += b * damping_.viscous * masses[i] * p[i];
    }
  }
}

void MechanicalSystem::add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const {
  linearized().add_linearized_diagonal(a, b, diagonal);
  if (damping_.viscous > 0.0 && b != 0.0) {
    const auto masses = model_.masses();
    for (std::size_t i = 0; i < diagonal.size(); ++i) {
      diagonal[i] += b * damping_.viscous * masses[i] * Mat3::Identity();
    }
  }
}

bool MechanicalSystem::assemble_linearization(double a, double b, BlockSparseMatrix& matrix) const {
  if (!linearized().assemble_linearization(a, b, matrix)) {
    return false;
  }
  if (damping_.viscous > 0.0 && b != 0.0) {
    const auto masses = model_.masses();
    auto values = matrix.values();
    for (std::size_t i = 0; i < matrix.rows(); ++i) {
      values[matrix.diagonal(static_cast<VertexId>(i))] +=
          b * damping_.viscous * masses[i] * Mat3::Identity();
    }
  }
  return true;
}

void MechanicalSystem::external_forces(double, std::span<Vec3> f) const {
  const auto masses = model_.masses();
  for (std::size_t i = 0; i < f.size(); ++i) {
    f[i] += masses[i] * conditions_.gravity() + conditions_.point_force(static_cast<VertexId>(i));
  }
}

double MechanicalSystem::potential_energy(double, std::span<const Vec3> x) const {
  double energy = model_.elastic_energy(x);
  const auto masses = model_.masses();
  for (std::size_t i = 0; i < x.size(); ++i) {
    const auto vertex = static_cast<VertexId>(i);
    // Conservative loads: gravity and constant point forces, measured from the rest shape.
    energy -= (masses[i] * conditions_.gravity() + conditions_.point_force(vertex))
                  .dot(x[i] - mesh_.rest_position(vertex));
  }
  return energy;
}

double MechanicalSystem::max_frequency() const {
  return model_.max_vertex_frequency();
}

void MechanicalSystem::end_step(double dt, std::span<Vec3> v) {
  if (damping_.penalty > 0.0) {
    const double factor = std::exp(-damping_.penalty * dt);
    for (Vec3& velocity : v) {
      velocity *= factor;
    }
  }
}

void MechanicalSystem::end_step(double dt, VertexId, Vec3& v) {
  if (damping_.penalty > 0.0) {
    v *= std::exp(-damping_.penalty * dt);
  }
}

void MechanicalSystem::begin_step(double /*t*/, std::span<Vec3> x, std::span<Vec3> v) {
  if (!(guard_.min_volume_ratio > 0.0)) {
    return;
  }
  step_start_.assign(x.begin(), x.end());
  if (mesh_.revision() != revision_checked_) {
    // A cut's children are as right side out as their parent was, but thinner than their
    // share of it where the parent was: pushed back before the step. The state the edit left
    // is the fallback's start (cut edits keep every tetrahedron right side out, at rest and
    // as deformed).
    note(keep_right_side_out(
        mesh_, model_.masses(),
        [this](VertexId vertex) { return conditions_.is_constrained(vertex); }, guard_, step_start_,
        x, v));
    step_start_.assign(x.begin(), x.end());
  }
}

void MechanicalSystem::finish_step(double /*t*/, std::span<Vec3> x, std::span<Vec3> v) {
  if (!(guard_.min_volume_ratio > 0.0)) {
    return;
  }
  note(keep_right_side_out(
      mesh_, model_.masses(),
      [this](VertexId vertex) { return conditions_.is_constrained(vertex); }, guard_, step_start_,
      x, v));
  revision_checked_ = mesh_.revision();
}

void MechanicalSystem::note(const InversionGuardOutcome& outcome) {
  guarded_tets_ += outcome.corrected;
  guarded_tets_most_ = std::max(guarded_tets_most_, outcome.corrected);
  backtracked_ += outcome.backtracked;
  backtracked_most_ = std::max(backtracked_most_, outcome.backtracked);
}

void apply_constraints(DynamicSystem& system, double t, std::span<Vec3> x, std::span<Vec3> v) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    const auto vertex = static_cast<VertexId>(i);
    if (system.is_constrained(vertex)) {
      system.prescribed_state(t, vertex, x[i], v[i]);
    }
  }
}

void MechanicalSystem::extend_vertex_values(std::vector<Vec3>& values) const {
  const std::size_t first = values.size();
  resize_for_edits(values, mesh_.vertex_count(), Vec3(Vec3::Zero()));
  // Parents always precede their children, so one pass in order suffices.
  for (std::size_t v = first; v < values.size(); ++v) {
    const VertexOrigin& origin = mesh_.vertex_origin(static_cast<VertexId>(v));
    Vec3 value = Vec3::Zero();
    for (int k = 0; k < origin.parent_count; ++k) {
      const auto parent = static_cast<std::size_t>(origin.parents[static_cast<std::size_t>(k)]);
      const double weight = origin.kind == VertexOrigin::Kind::kDuplicate
                                ? 1.0
                                : origin.weights[static_cast<std::size_t>(k)];
      if (parent < v) {
        value += weight * values[parent];
      }
    }
    values[v] = value;
  }
}

}  // namespace incise
