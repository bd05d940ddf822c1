// The visual surface follows the XFEM cut: after every pose it is closed (every edge in two
// triangles, once each way), encloses the original volume, and its points sit where their
// embeddings put them; a full cut leaves two closed pieces, a half cut one.

#include "incise/xfem/visual_surface.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "blade_walks.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/disjoint_sets.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/xfem/xfem_cutter.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

/// A bar 8 x 2 x 2 cm of 8 x 2 x 2 cells.
TetMesh bar() {
  return make_box_grid({{8, 2, 2}, Vec3(0.08, 0.02, 0.02), Vec3::Zero(), 6});
}

/// The boundary of a finer box inside the bar, 2 mm in from its faces: a visual surface.
SurfaceMesh inner_box() {
  const TetMesh fine =
      make_box_grid({{19, 4, 4}, Vec3(0.076, 0.016, 0.016), Vec3(0.002, 0.002, 0.002), 6});
  SurfaceMesh surface;
  surface.points.assign(fine.rest_positions().begin(), fine.rest_positions().end());
  for (const BoundaryFace& face : boundary_faces(fine)) {
    surface.triangles.push_back(face.vertices);
  }
  return surface;
}

int surface_pieces(const VisualSurface& visual) {
  DisjointSets sets(visual.rest_points().size());
  for (const Triangle& t : visual.triangles()) {
    sets.join(t[0], t[1]);
    sets.join(t[0], t[2]);
  }
  std::vector<bool> root(visual.rest_points().size(), false);
  int pieces = 0;
  for (const Triangle& t : visual.triangles()) {
    const auto r = static_cast<std::size_t>(sets.find(t[0]));
    if (!root[r]) {
      root[r] = true;
      ++pieces;
    }
  }
  return pieces;
}

void expect_closed(const TetMesh& mesh, const VisualSurface& visual, double volume,
                   double tolerance, const std::string& where) {
  EXPECT_TRUE(is_watertight(visual.triangles())) << where;
  EXPECT_NEAR(enclosed_volume(visual.rest_points(), visual.triangles()), volume, tolerance * volume)
      << where;
  // Evaluated at the rest positions of the physics nodes, the embeddings give the rest points.
  const std::vector<Vec3> at_rest = visual.positions(
      std::vector<Vec3>(mesh.rest_positions().begin(), mesh.rest_positions().end()));
  for (std::size_t i = 0; i < at_rest.size(); ++i) {
    ASSERT_LT((at_rest[i] - visual.rest_points()[i]).norm(), 1e-12) << where << " point " << i;
  }
}

TEST(VisualSurface, ThePictureIsCutUpToTheBladeWhileThePhysicsWaits) {
  // A blade swept along y across the bar, 1 mm per pose through 1 cm cells: the physics splits
  // a tetrahedron once the blade has crossed it completely, a cell behind the blade; the
  // picture is cut up to the blade itself (its cut faces reach the blade's line), and stays
  // closed, with its volume, where the physics is still whole.
  TetMesh mesh = bar();
  const SurfaceMesh surface = inner_box();
  const double volume = enclosed_volume(surface.points, surface.triangles);
  VisualSurface visual(mesh, surface.points, surface.triangles);
  XfemCutter cutter(mesh);
  const double x = 0.0437;
  cutter.start({0.0, Vec3(x, -0.005, -0.01), Vec3(x, -0.005, 0.03)});
  double picture_lag = 0.0;  // m: the blade's y beyond the picture's cut, largest
  double physics_lag = 0.0;  // m: the blade's y beyond the split elements, largest
  int poses_inside = 0;
  for (int i = 1; i <= 20; ++i) {
    const double y = -0.005 + 0.001 * i;
    cutter.move_to({0.1 * i, Vec3(x, y, -0.01), Vec3(x, y, 0.03)});
    visual.follow(mesh, cutter);
    expect_closed(mesh, visual, volume, 1e-6, "pose " + std::to_string(i));
    if (y < 0.004) {
      continue;  // the blade has not reached the visual surface (2 mm in) far enough
    }
    ++poses_inside;
    double picture = -1.0;
    for (std::size_t t = 0; t < visual.triangles().size(); ++t) {
      if (visual.on_cut()[t] != 0) {
        for (VertexId v : visual.triangles()[t]) {
          picture = std::max(picture, visual.rest_points()[static_cast<std::size_t>(v)].y());
        }
      }
    }
    double physics = -1.0;
    for (std::size_t t = 0; t < cutter.rest_tet_count(); ++t) {
      if (cutter.cut_of(static_cast<TetId>(t))) {
        for (VertexId v : mesh.tet(static_cast<TetId>(t))) {
          physics = std::max(physics, mesh.rest_position(v).y());
        }
      }
    }
    picture_lag = std::max(picture_lag, y - picture);
    physics_lag = std::max(physics_lag, y - std::min(physics, y));
  }
  EXPECT_GT(poses_inside, 10);
  EXPECT_LT(picture_lag, 1e-9) << "the picture's cut reaches the blade";
  EXPECT_GT(physics_lag, 0.002) << "the physics waits for full crossings (1 cm cells)";
  EXPECT_EQ(visual.failures(), 0U);
  EXPECT_EQ(visual.front_failures(), 0U);
}

TEST(VisualSurface, StaysClosedAndEnclosesItsVolumeAfterEveryPose) {
  TetMesh mesh = bar();
  const SurfaceMesh surface = inner_box();
  const double volume = enclosed_volume(surface.points, surface.triangles);
  EXPECT_NEAR(volume, 0.076 * 0.016 * 0.016, 1e-15);
  VisualSurface visual(mesh, surface.points, surface.triangles);
  EXPECT_EQ(visual.outside_points(), 0u);
  XfemCutter cutter(mesh);
  const double x = 0.0437;
  cutter.start({0.0, Vec3(x, -0.01, -0.01), Vec3(x, -0.01, 0.03)});
  for (int i = 1; i <= 13; ++i) {
    const double y = -0.01 + 0.04 * i / 13;
    cutter.move_to({0.1 * i, Vec3(x, y, -0.01), Vec3(x, y, 0.03)});
    visual.follow(mesh, cutter);
    expect_closed(mesh, visual, volume, 1e-6, "pose " + std::to_string(i));
    if (i == 6) {
      EXPECT_EQ(surface_pieces(visual), 1);  // half way: one piece, open to the blade
    }
  }
  EXPECT_EQ(surface_pieces(visual), 2);
  std::size_t cut_triangles = 0;
  for (std::uint8_t on : visual.on_cut()) {
    cut_triangles += on;
  }
  EXPECT_GT(cut_triangles, 0u);
  // Each visual point is carried by one physics piece: lift the piece holding vertex 0 by
  // 1 cm and exactly the visual points of one surface piece follow.
  DisjointSets physics(mesh.vertex_count());
  for (const Tet& tet : mesh.tets()) {
    for (VertexId v : tet) {
      physics.join(v, tet[0]);
    }
  }
  std::vector<Vec3> nodes(mesh.rest_positions().begin(), mesh.rest_positions().end());
  const VertexId lifted = physics.find(0);
  for (std::size_t v = 0; v < nodes.size(); ++v) {
    if (physics.find(static_cast<VertexId>(v)) == lifted) {
      nodes[v].z() += 0.01;
    }
  }
  const std::vector<Vec3> moved = visual.positions(nodes);
  std::size_t up = 0;
  for (std::size_t i = 0; i < moved.size(); ++i) {
    const double rise = moved[i].z() - visual.rest_points()[i].z();
    EXPECT_TRUE(std::abs(rise) < 1e-12 || std::abs(rise - 0.01) < 1e-12) << "point " << i;
    up += rise > 0.005 ? 1 : 0;
  }
  EXPECT_GT(up, 0u);
  EXPECT_LT(up, moved.size());
}

TEST(VisualSurface, ASurfaceStickingOutOfTheBodyIsCarriedByItsNearestElements) {
  const auto mesh_path = test::data_file("sofa/liver.msh");
  const auto surface_path = test::data_file("sofa/liver-smooth.obj");
  if (!std::filesystem::exists(mesh_path) || !std::filesystem::exists(surface_path)) {
    GTEST_SKIP() << "no data meshes";
  }
  TetMesh mesh = read_tet_mesh(mesh_path).mesh;
  const SurfaceMesh surface = read_surface(surface_path);
  const double volume = enclosed_volume(surface.points, surface.triangles);
  VisualSurface visual(mesh, surface.points, surface.triangles);
  std::printf("liver-smooth.obj: %zu points, %zu outside liver.msh, volume %.4g\n",
              surface.points.size(), visual.outside_points(), volume);
  XfemCutter cutter(mesh);
  test::play(cutter, test::sweep_along_x(test::bounds(mesh), 0.513, 1.05, 24, 0.05, 0.04),
             [&](std::size_t) { visual.follow(mesh, cutter); });
  std::printf(
      "after the full cut: %zu triangles, watertight %d, volume %.4g (%.3g %%), %d pieces, "
      "%zu updates CGAL gave up on\n",
      visual.triangles().size(), is_watertight(visual.triangles()) ? 1 : 0,
      enclosed_volume(visual.rest_points(), visual.triangles()),
      100.0 * (enclosed_volume(visual.rest_points(), visual.triangles()) / volume - 1.0),
      surface_pieces(visual), visual.failures());
  EXPECT_NEAR(enclosed_volume(visual.rest_points(), visual.triangles()), volume, 0.01 * volume);
}

}  // namespace
}  // namespace incise
