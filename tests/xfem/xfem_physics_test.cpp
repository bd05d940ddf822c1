// XFEM physics through the virtual mesh: each virtual element is a corotational element of its
// own (its own rotation), weighted by its material fraction in stiffness and mass (Young's
// modulus and density scaled by the fraction). A cantilever cut through lets its free end
// fall as a body of its own while the held part stays up; the uncut bar does not fall.

#include <gtest/gtest.h>

#include "incise/mesh/generators.hpp"
#include "incise/physics/boundary_conditions.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"
#include "incise/xfem/virtual_mesh.hpp"

namespace incise {
namespace {

constexpr double kCut = 0.0437;  // m along the bar, between grid planes

struct Result {
  double free_end_drop = 0.0;  ///< m, mean over the nodes beyond the cut
  double held_drop = 0.0;      ///< m, largest over the nodes before it
  double volume = 0.0;         ///< m^3 of material
  int pieces = 0;
  bool finite = true;
};

/// A 10 x 2 x 2 cm bar held at x = 0, under gravity, cut (or not) through x = kCut, run with
/// backward Euler for `steps` steps of 10 ms.
Result hang(bool cut, int steps) {
  const TetMesh rest = make_box_grid({{10, 2, 2}, Vec3(0.1, 0.02, 0.02), Vec3::Zero(), 6});
  std::vector<std::optional<ElementCut>> cuts(rest.tet_count());
  if (cut) {
    for (std::size_t t = 0; t < rest.tet_count(); ++t) {
      const Tet& tet = rest.tet(static_cast<TetId>(t));
      cuts[t] = cut_by_plane({rest.rest_position(tet[0]), rest.rest_position(tet[1]),
                              rest.rest_position(tet[2]), rest.rest_position(tet[3])},
                             Vec3(kCut, 0, 0), Vec3::UnitX());
    }
  }
  const VirtualMesh body = build_virtual_mesh(rest, cuts);
  Result result;
  result.volume = material_volume(body, rest);
  (void)virtual_pieces(body, &result.pieces);

  Material tissue;
  tissue.young_modulus = 1e6;  // Pa (rubber-stiff: the held bar barely sags)
  tissue.poisson_ratio = 0.3;
  tissue.density = 1000.0;  // kg/m^3
  MaterialAssignment materials;
  for (std::size_t e = 0; e < body.elements.size(); ++e) {
    Material weighted = tissue;
    weighted.young_modulus *= body.fraction[e];
    weighted.density *= body.fraction[e];
    materials.table.push_back(weighted);
    materials.ids.push_back(static_cast<int>(e));
  }
  TetMesh mesh(body.rest_positions, body.elements);
  CorotationalFemModel model(mesh, materials);
  BoundaryConditions conditions(mesh);
  std::vector<VertexId> held;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.rest_position(static_cast<VertexId>(v)).x() == 0.0) {
      held.push_back(static_cast<VertexId>(v));
    }
  }
  conditions.fix(held);
  conditions.set_gravity(Vec3(0, 0, -9.81));
  MechanicalSystem system(mesh, model, conditions);
  SimulationState state(mesh);
  BackwardEuler integrator;
  for (int s = 0; s < steps; ++s) {
    integrator.step(system, state.x.values(), state.v.values(), s * 0.01, 0.01);
  }
  int beyond = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3 x = state.x.values()[v];
    result.finite = result.finite && x.allFinite();
    const double drop = mesh.rest_position(static_cast<VertexId>(v)).z() - x.z();
    if (mesh.rest_position(static_cast<VertexId>(v)).x() > kCut + 0.01) {
      result.free_end_drop += drop;
      ++beyond;
    } else if (mesh.rest_position(static_cast<VertexId>(v)).x() < kCut - 0.01) {
      result.held_drop = std::max(result.held_drop, drop);
    }
  }
  result.free_end_drop /= beyond;
  return result;
}

TEST(XfemPhysics, ACutCantileverDropsItsFreeEnd) {
  const int steps = 20;
  const Result whole = hang(false, steps);
  const Result cut = hang(true, steps);
  ASSERT_TRUE(whole.finite);
  ASSERT_TRUE(cut.finite);
  EXPECT_EQ(whole.pieces, 1);
  EXPECT_EQ(cut.pieces, 2);
  EXPECT_NEAR(cut.volume, whole.volume, 1e-15);
  // Backward Euler's free fall from rest: g dt^2 n (n + 1) / 2.
  const double free_fall = 9.81 * 0.01 * 0.01 * steps * (steps + 1) / 2.0;
  EXPECT_NEAR(cut.free_end_drop, free_fall, 0.01 * free_fall);
  EXPECT_LT(whole.free_end_drop, 0.25 * free_fall);  // held by the rest of the bar
  EXPECT_LT(cut.held_drop, 0.25 * free_fall);        // the held part stays up
}

}  // namespace
}  // namespace incise
