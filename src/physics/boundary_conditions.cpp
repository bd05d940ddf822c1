#include "incise/physics/boundary_conditions.hpp"

#include <algorithm>
#include <cmath>

#include "incise/core/error.hpp"

namespace incise {

BoundaryConditions::BoundaryConditions(TetMesh& mesh)
    : mesh_(mesh),
      group_(mesh, -1, VertexRule::kDefault),
      point_force_(mesh, Vec3::Zero(), VertexRule::kDefault) {
  group_.set_hook([](VertexData<std::int32_t>& group, VertexId vertex, const VertexOrigin& origin) {
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      group[vertex] = group[origin.parents[0]];
      return;
    }
    if (origin.kind != VertexOrigin::Kind::kCombination) {
      return;
    }
    std::int32_t common = -2;
    for (int k = 0; k < origin.parent_count; ++k) {
      if (origin.weights[k] <= 0.0) {
        continue;
      }
      const std::int32_t parent = group[origin.parents[k]];
      common = common == -2 ? parent : (common == parent ? common : -1);
    }
    group[vertex] = std::max(common, -1);
  });
}

void BoundaryConditions::assign(std::span<const VertexId> vertices, int group) {
  for (VertexId v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= mesh_.vertex_count()) {
      throw InputError("boundary condition on vertex " + std::to_string(v) +
                       ", which does not exist");
    }
    group_[v] = group;
  }
}

void BoundaryConditions::fix(std::span<const VertexId> vertices) {
  prescribe_displacement(vertices, Vec3::Zero(), 0.0);
}

void BoundaryConditions::prescribe_displacement(std::span<const VertexId> vertices,
                                                const Vec3& displacement, double ramp_time) {
  if (!displacement.allFinite() || !(ramp_time >= 0.0) || !std::isfinite(ramp_time)) {
    throw InputError("prescribed displacement must be finite with a non-negative ramp time");
  }
  motions_.push_back({displacement, ramp_time});
  assign(vertices, static_cast<int>(motions_.size() - 1));
}

void BoundaryConditions::add_force(std::span<const VertexId> vertices, const Vec3& total_force) {
  if (vertices.empty()) {
    throw InputError("a force needs at least one vertex to act on");
  }
  if (!total_force.allFinite()) {
    throw InputError("force must be finite");
  }
  for (VertexId v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= mesh_.vertex_count()) {
      throw InputError("force on vertex " + std::to_string(v) + ", which does not exist");
    }
    point_force_[v] += total_force / static_cast<double>(vertices.size());
  }
}

std::size_t BoundaryConditions::constrained_count() const {
  return static_cast<std::size_t>(std::count_if(group_.values().begin(), group_.values().end(),
                                                [](std::int32_t g) { return g >= 0; }));
}

void BoundaryConditions::prescribed_state(double t, VertexId vertex, const Vec3& rest, Vec3& x,
                                          Vec3& v) const {
  const Motion& motion = motions_[static_cast<std::size_t>(group_[vertex])];
  if (motion.ramp_time > 0.0 && t < motion.ramp_time) {
    x = rest + motion.displacement * (t / motion.ramp_time);
    v = motion.displacement / motion.ramp_time;
  } else {
    x = rest + motion.displacement;
    v = Vec3::Zero();
  }
}

std::vector<VertexId> vertices_in_box(const TetMesh& mesh, const Vec3& low, const Vec3& high) {
  std::vector<VertexId> inside;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3& p = mesh.rest_position(static_cast<VertexId>(v));
    if ((p.array() >= low.array()).all() && (p.array() <= high.array()).all()) {
      inside.push_back(static_cast<VertexId>(v));
    }
  }
  return inside;
}

}  // namespace incise
