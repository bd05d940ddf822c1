#include "incise/physics/lumped_mass.hpp"

#include <cmath>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

TetData<double>::Hook mass_split_by_volume(TetMesh* const& mesh) {
  return [&mesh](TetData<double>& mass, TetId, std::span<const TetId> children,
                 const double& parent_mass) {
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

}  // namespace incise
