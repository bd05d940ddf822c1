// The subdivision cutter tests its candidates on worker threads (collision detection, the
// blade line, the active set): the cut must be the same tetrahedra, bit for bit, at any thread
// count.

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cstddef>
#include <vector>

#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {
namespace {

struct CutResult {
  std::vector<Vec3> rest_positions;
  std::vector<Tet> tets;
  std::size_t active_tets = 0;
};

/// A 16^3-cell box (24,576 tets, 6.25 mm cells) cut by a tilted blade in general position,
/// 2 mm per move, in the body's current (sheared) configuration: thousands of candidates per
/// move, enough for the parallel loops to split them between threads.
CutResult cut_with_threads(int threads) {
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                  static_cast<std::size_t>(threads));
  BoxGridOptions grid;
  grid.cells = {16, 16, 16};
  grid.size = Vec3(0.1, 0.1, 0.1);  // m
  TetMesh mesh = make_box_grid(grid);
  VertexData<Vec3> positions(mesh, Vec3::Zero());  // follows the mesh's new vertices
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3& rest = mesh.rest_position(static_cast<VertexId>(v));
    positions[static_cast<VertexId>(v)] = rest + Vec3(0.1 * rest.z(), 0.0, 0.0);  // sheared
  }
  SubdivisionCutter cutter(mesh, CutterOptions{}, &positions);
  std::vector<BladePose> path;
  for (int i = 0; i <= 40; ++i) {
    const double y = -0.01 + 0.002 * i;  // m
    path.push_back({0.01 * i, Vec3(0.0437, y, -0.01), Vec3(0.0611, y + 0.013, 0.12)});
  }
  cutter.start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    cutter.move_to(path[i]);
  }
  EXPECT_TRUE(validate(mesh).ok());
  CutResult result;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    result.rest_positions.push_back(mesh.rest_position(static_cast<VertexId>(v)));
  }
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    result.tets.push_back(mesh.tet(static_cast<TetId>(t)));
  }
  result.active_tets = cutter.active_tets().size();
  return result;
}

TEST(ParallelCut, TheSameTetrahedraWhateverTheThreadCount) {
  const CutResult one = cut_with_threads(1);
  ASSERT_GT(one.tets.size(), 24576U + 1000U);  // the blade cut a good part of the body
  EXPECT_GT(one.active_tets, 0U);
  for (int threads : {2, 4}) {
    const CutResult many = cut_with_threads(threads);
    ASSERT_EQ(one.tets.size(), many.tets.size()) << threads << " threads";
    ASSERT_EQ(one.rest_positions.size(), many.rest_positions.size()) << threads << " threads";
    for (std::size_t t = 0; t < one.tets.size(); ++t) {
      ASSERT_EQ(one.tets[t], many.tets[t]) << "tetrahedron " << t << ", " << threads << " threads";
    }
    for (std::size_t v = 0; v < one.rest_positions.size(); ++v) {
      ASSERT_EQ(one.rest_positions[v], many.rest_positions[v])  // bit-identical
          << "vertex " << v << ", " << threads << " threads";
    }
    EXPECT_EQ(one.active_tets, many.active_tets) << threads << " threads";
  }
}

}  // namespace
}  // namespace incise
