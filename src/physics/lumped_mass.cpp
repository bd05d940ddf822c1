#include "incise/physics/lumped_mass.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {
namespace {

/// Whether two or more tetrahedra have the same rest corners (as sets of points).
bool overlap_exactly(const TetMesh& mesh, std::span<const TetId> tets) {
  if (tets.size() < 2) {
    return false;
  }
  const auto corners = [&](TetId t) {
    std::array<std::array<double, 3>, 4> points{};
    for (std::size_t k = 0; k < 4; ++k) {
      const Vec3& p = mesh.rest_position(mesh.tet(t)[k]);
      points[k] = {p.x(), p.y(), p.z()};
    }
    std::sort(points.begin(), points.end());
    return points;
  };
  const auto first = corners(tets[0]);
  return std::all_of(tets.begin() + 1, tets.end(), [&](TetId t) { return corners(t) == first; });
}

}  // namespace

TetData<double>::Hook mass_split_by_volume(TetMesh* const& mesh) {
  return [&mesh](TetData<double>& mass, TetId, std::span<const TetId> children,
                 const double& parent_mass) {
    if (overlap_exactly(*mesh, children)) {
      // Virtual elements (XFEM) integrate the same rest tetrahedron, each weighted by its
      // material fraction on the mesh: each carries the whole tetrahedron's mass.
      for (TetId child : children) {
        mass[child] = parent_mass;
      }
      return;
    }
    double volume_sum = 0.0;
    for (TetId child : children) {
      volume_sum += std::abs(signed_volume(*mesh, child));
    }
    for (TetId child : children) {
      mass[child] = volume_sum > 0.0
                        ? parent_mass * std::abs(signed_volume(*mesh, child)) / volume_sum
                        : parent_mass / static_cast<double>(children.size());
    }
  };
}

TetData<double>::AbsorbHook mass_absorbed() {
  return [](TetData<double>& mass, TetId into, const double& removed_mass) {
    mass[into] += removed_mass;
  };
}

void conserve_mass(TetData<double>& mass, TetMesh* const& mesh) {
  mass.set_hook(mass_split_by_volume(mesh));
  mass.set_absorb_hook(mass_absorbed());
}

double vertex_lumped_mass(const TetMesh& mesh, const TetData<double>& tet_mass, VertexId vertex) {
  double mass = 0.0;
  for (TetId tet : mesh.vertex_tets(vertex)) {
    mass += 0.25 * tet_mass[tet] * mesh.material_fraction(tet);
  }
  return mass;
}

}  // namespace incise
