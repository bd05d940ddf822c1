// The inversion guard: a tetrahedron pushed inside out comes back right side out with its
// centre of mass and momentum kept and no kinetic energy gained; fixed corners stay; where
// projection is not allowed to settle, the fallback brings the state back towards the start.

#include "incise/physics/inversion_guard.hpp"

#include <gtest/gtest.h>

#include "incise/mesh/tet_mesh.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {
namespace {

/// Two tetrahedra sharing the face (0, 1, 2): apexes 3 above it and 4 below (m).
TetMesh two_tets() {
  return TetMesh(
      {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.2, 0.2, 1), Vec3(0.3, 0.3, -1)},
      {Tet{0, 1, 2, 3}, Tet{0, 2, 1, 4}});
}

double volume_at(const TetMesh& mesh, TetId t, std::span<const Vec3> x) {
  const Tet& tet = mesh.tet(t);
  return signed_volume(x[static_cast<std::size_t>(tet[0])], x[static_cast<std::size_t>(tet[1])],
                       x[static_cast<std::size_t>(tet[2])], x[static_cast<std::size_t>(tet[3])]);
}

TEST(InversionGuard, PushesAnInvertedTetrahedronBackKeepingMomentum) {
  const TetMesh mesh = two_tets();
  std::vector<Vec3> x(mesh.rest_positions().begin(), mesh.rest_positions().end());
  const std::vector<double> masses{1.0, 2.0, 1.5, 0.5, 1.0};  // kg
  // Apex 3 driven through the shared face, still moving down.
  x[3] = Vec3(0.2, 0.2, -0.3);
  std::vector<Vec3> v(x.size(), Vec3::Zero());
  v[3] = Vec3(0, 0, -2.0);
  v[0] = Vec3(0.5, 0, 0);
  ASSERT_LT(volume_at(mesh, 0, x), 0.0);
  const auto moment = [&](const std::vector<Vec3>& values) {
    Vec3 sum = Vec3::Zero();
    for (std::size_t i = 0; i < values.size(); ++i) {
      sum += masses[i] * values[i];
    }
    return sum;
  };
  const auto kinetic = [&] {
    double energy = 0.0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      energy += 0.5 * masses[i] * v[i].squaredNorm();
    }
    return energy;
  };
  const Vec3 centre_before = moment(x);
  const Vec3 momentum_before = moment(v);
  const double energy_before = kinetic();
  InversionGuardParameters parameters;
  const InversionGuardOutcome outcome = keep_right_side_out(
      mesh, masses, [](VertexId) { return false; }, parameters, {}, x, v);
  EXPECT_GE(outcome.corrected, 1u);
  EXPECT_EQ(outcome.left_inverted, 0u);
  const double rest_volume = signed_volume(mesh, 0);
  EXPECT_GE(volume_at(mesh, 0, x), 0.5 * parameters.min_volume_ratio * rest_volume);
  EXPECT_GT(volume_at(mesh, 1, x), 0.0);
  EXPECT_TRUE(inverted_at(mesh, x).empty());
  EXPECT_LT((moment(x) - centre_before).norm(), 1e-12);
  EXPECT_LT((moment(v) - momentum_before).norm(), 1e-12);
  EXPECT_LE(kinetic(), energy_before + 1e-12);
}

TEST(InversionGuard, FixedCornersStayAndAGuardOfZeroDoesNothing) {
  const TetMesh mesh = two_tets();
  std::vector<Vec3> x(mesh.rest_positions().begin(), mesh.rest_positions().end());
  x[3] = Vec3(0.2, 0.2, -0.3);
  std::vector<Vec3> v(x.size(), Vec3::Zero());
  const std::vector<double> masses(x.size(), 1.0);
  const std::vector<Vec3> inverted = x;
  InversionGuardParameters off;
  off.min_volume_ratio = 0.0;
  (void)keep_right_side_out(
      mesh, masses, [](VertexId) { return false; }, off, {}, x, v);
  EXPECT_EQ(x, inverted);
  // Only the apex may move: the face stays where it is and the apex comes back above it.
  const auto only_apex = [](VertexId vertex) { return vertex != 3; };
  const InversionGuardOutcome outcome =
      keep_right_side_out(mesh, masses, only_apex, InversionGuardParameters{}, {}, x, v);
  EXPECT_EQ(outcome.left_inverted, 0u);
  for (VertexId vertex : {0, 1, 2, 4}) {
    EXPECT_EQ(x[static_cast<std::size_t>(vertex)], inverted[static_cast<std::size_t>(vertex)]);
  }
  EXPECT_GT(x[3].z(), 0.0);
}

TEST(InversionGuard, WithoutPassesItFallsBackTowardsTheStart) {
  const TetMesh mesh = two_tets();
  const std::vector<Vec3> start(mesh.rest_positions().begin(), mesh.rest_positions().end());
  std::vector<Vec3> x = start;
  x[3] = Vec3(0.2, 0.2, -0.6);
  x[4] = Vec3(0.3, 0.3, -1.2);
  std::vector<Vec3> v(x.size(), Vec3(0, 0, -1.0));
  const std::vector<Vec3> stepped = x;
  const std::vector<double> masses(x.size(), 1.0);
  InversionGuardParameters parameters;
  parameters.max_passes = 0;  // no projection: what a tangle that never settles leaves
  const InversionGuardOutcome outcome = keep_right_side_out(
      mesh, masses, [](VertexId vertex) { return vertex != 3; }, parameters, start, x, v);
  EXPECT_EQ(outcome.left_inverted, 0u);
  EXPECT_TRUE(inverted_at(mesh, x).empty());
  // Whatever moved lies between where the step started and where it ended.
  for (std::size_t i = 0; i < x.size(); ++i) {
    const Vec3 along = stepped[i] - start[i];
    const Vec3 offset = x[i] - start[i];
    EXPECT_LT(offset.cross(along).norm(), 1e-12) << i;
    EXPECT_GE(offset.dot(along), -1e-15) << i;
  }
}

}  // namespace
}  // namespace incise
