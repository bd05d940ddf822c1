// Virtual elements clipped to their sides: the pieces fill each side exactly (their volumes
// are the side volumes the physics integrates) and positively; over a cut body they sum to
// the body's rest volume, where the virtual elements as they are count split tetrahedra twice.

#include "incise/xfem/clipped_elements.hpp"

#include <gtest/gtest.h>

#include <random>

#include "incise/mesh/generators.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/xfem/xfem_cutter.hpp"

namespace incise {
namespace {

double volume_of(const std::array<Vec3, 4>& x) {
  return signed_volume(x[0], x[1], x[2], x[3]);
}

TEST(ClippedElements, SidePiecesFillEachSideExactlyAndPositively) {
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int cuts = 0;
  int negative = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::array<Vec3, 4> x;
    for (Vec3& p : x) {
      p = Vec3(unit(random), unit(random), unit(random));
    }
    if (volume_of(x) < 0.0) {
      std::swap(x[2], x[3]);
    }
    if (volume_of(x) < 0.02) {
      continue;
    }
    // A bent cut: each crossing anywhere along its edge (non-planar quads included).
    ElementCut cut;
    for (bool& b : cut.on_b) {
      b = unit(random) > 0.0;
    }
    for (double& t : cut.crossing) {
      t = 0.02 + 0.96 * (0.5 + 0.5 * unit(random));
    }
    if (!cut.splits()) {
      continue;
    }
    ++cuts;
    const SideVolumes expected = side_volumes(x, cut);
    for (const bool side_b : {false, true}) {
      double sum = 0.0;
      for (const auto& piece : side_tetrahedra(x, cut, side_b)) {
        sum += volume_of(piece);
        negative += volume_of(piece) < 0.0 ? 1 : 0;
      }
      EXPECT_NEAR(sum, side_b ? expected.b : expected.a, 1e-12) << "trial " << trial;
    }
  }
  EXPECT_GT(cuts, 1000);
  EXPECT_EQ(negative, 0);
  // A cut that does not split: the whole tetrahedron to the side of its corners.
  const std::array<Vec3, 4> x{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  ElementCut whole;
  EXPECT_EQ(side_tetrahedra(x, whole, false).size(), 1u);
  EXPECT_TRUE(side_tetrahedra(x, whole, true).empty());
}

TEST(ClippedElements, ACutBarClipsToItsRestVolumeWhereVirtualElementsOverlap) {
  TetMesh mesh = make_box_grid({{8, 2, 2}, Vec3(0.08, 0.02, 0.02), Vec3::Zero(), 6});
  const double rest_volume = total_volume(mesh);
  XfemCutter cutter(mesh);
  cutter.start({0.0, Vec3(0.0437, -0.01, -0.01), Vec3(0.0437, -0.01, 0.03)});
  for (int i = 1; i <= 13; ++i) {
    const double y = -0.01 + 0.04 * i / 13;
    cutter.move_to({0.1 * i, Vec3(0.0437, y, -0.01), Vec3(0.0437, y, 0.03)});
  }
  ASSERT_GT(cutter.stats().elements_split, 0u);
  // The virtual elements as written count each split tetrahedron twice.
  double elements = 0.0;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    elements += signed_volume(mesh, static_cast<TetId>(t));
  }
  EXPECT_GT(elements, rest_volume * 1.01);
  // The clipped pieces fill the body's volume once, each side its share.
  const ClippedElements rest = clip_virtual_elements(mesh, cutter);
  double clipped = 0.0;
  double left = 0.0;
  for (std::size_t t = 0; t < rest.tets.size(); ++t) {
    std::array<Vec3, 4> x;
    Vec3 centre = Vec3::Zero();
    for (std::size_t k = 0; k < 4; ++k) {
      x[k] = rest.points[static_cast<std::size_t>(rest.tets[t][k])];
      centre += x[k] / 4.0;
    }
    const double v = volume_of(x);
    EXPECT_GT(v, 0.0) << "piece " << t;
    clipped += v;
    left += centre.x() < 0.0437 ? v : 0.0;
  }
  EXPECT_NEAR(clipped, rest_volume, 1e-12 * rest_volume);
  EXPECT_NEAR(left, 0.0437 / 0.08 * rest_volume, 1e-9 * rest_volume);
}

}  // namespace
}  // namespace incise
