// What a user cares about when cutting real anatomy: a cut that crosses the body completely
// separates it (by shared faces and by shared vertices), into pieces that each lie on one side
// of the blade's plane, with no sliver shards; a cut that stops inside leaves it in one piece;
// and the result does not depend on whether the blade's path was sampled in 24 or 240 poses.
// Every tetrahedral mesh in ../shared/data (SOFA, SOFA-MOR, PBD, libigl), plus random blade
// walks over randomly perturbed grids and real meshes.

#include "incise/cut/separation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>

#include "blade_walks.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/cut/tet_grid.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/meshing/tetrahedralize.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

using test::boundary_area;
using test::bounds;
using test::Box;
using test::data_meshes;
using test::perturbed_grid;
using test::random_walk;
using test::sweep_along_x;
using test::walk_mesh;

struct Pieces {
  int by_faces = 0;
  int by_vertices = 0;
  std::vector<double> volumes;  ///< m^3, per face-connected piece
  std::vector<int> sides;       ///< -1 / +1: all centroids below / above the plane; 0: both
};

/// m: the snap distance at a point of the body before the cut: a tenth of the longest edge of
/// the input tetrahedron holding it (the cutter snaps crossings and blade points that far,
/// relative to the element it cuts). Null `input`, or a point in none: `fallback`.
double snap_band(const TetMesh* input, const TetGrid* grid, const Vec3& point, double fallback) {
  if (input == nullptr) {
    return fallback;
  }
  std::vector<TetId> near;
  grid->query(point, point, near);
  for (TetId t : near) {
    const std::array<Vec3, 4> c = rest_corners(*input, t);
    if (locate_in_tet(point, c[0], c[1], c[2], c[3]) != TetLocation::kOutside) {
      double longest = 0.0;
      for (const auto& e : tet_local::kEdges) {
        longest = std::max(longest, (c[e[0]] - c[e[1]]).norm());
      }
      return 0.1 * longest;
    }
  }
  return fallback;
}

/// The pieces of a cut mesh and the side of the plane y = plane_y each lies on. `input` (the
/// mesh before the cut) gives the snap band around the plane where a tetrahedron may lie on
/// either side; without it, a tenth of the tetrahedron's own longest edge.
Pieces pieces_across(const TetMesh& mesh, double plane_y, const TetMesh* input = nullptr) {
  Pieces pieces;
  const std::vector<int> component = tet_components(mesh, &pieces.by_faces);
  pieces.by_vertices = pieces_by_vertices(mesh);
  pieces.volumes.assign(static_cast<std::size_t>(pieces.by_faces), 0.0);
  std::vector<std::array<int, 2>> count(static_cast<std::size_t>(pieces.by_faces), {0, 0});
  TetMesh input_copy;
  std::unique_ptr<TetGrid> grid;
  if (input != nullptr) {
    input_copy = *input;
    grid = std::make_unique<TetGrid>(input_copy);
  }
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const std::array<Vec3, 4> c = rest_corners(mesh, static_cast<TetId>(t));
    const Vec3 centroid = (c[0] + c[1] + c[2] + c[3]) / 4.0;
    const auto piece = static_cast<std::size_t>(component[t]);
    pieces.volumes[piece] += std::abs(signed_volume(mesh, static_cast<TetId>(t)));
    // A tetrahedron closer to the plane than the snap distance may lie on either side: the
    // cut follows vertices snapped that far.
    double longest = 0.0;
    for (const auto& e : tet_local::kEdges) {
      longest = std::max(longest, (c[e[0]] - c[e[1]]).norm());
    }
    const double band =
        snap_band(input != nullptr ? &input_copy : nullptr, grid.get(), centroid, 0.1 * longest);
    if (std::abs(centroid.y() - plane_y) > band) {
      ++count[piece][centroid.y() < plane_y ? 0 : 1];
    }
  }
  for (const auto& [below, above] : count) {
    pieces.sides.push_back(below > 0 && above > 0 ? 0 : (below > 0 ? -1 : 1));
  }
  return pieces;
}

/// Cuts along `path`, checking after every `check_every`-th pose (and the last) that the mesh
/// is valid, the cut added no open or non-manifold boundary edge, and volume is conserved.
void cut_checked(TetMesh& mesh, const std::vector<BladePose>& path, std::size_t check_every,
                 const CutterOptions& options = {}) {
  const double volume = total_volume(mesh);
  const SurfaceEdgeCheck boundary_in = check_boundary(mesh);
  SubdivisionCutter cutter(mesh, options);
  cutter.start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    cutter.move_to(path[i]);
    if (i % check_every != 0 && i + 1 != path.size()) {
      continue;
    }
    const ValidationReport report = validate(mesh);
    ASSERT_TRUE(report.ok()) << "pose " << i << ":\n" << report.describe();
    const SurfaceEdgeCheck boundary = check_boundary(mesh);
    ASSERT_TRUE(cut_kept_boundary(boundary_in, boundary))
        << "pose " << i << ": open " << boundary.open_edges << " nonmanifold "
        << boundary.nonmanifold_edges << " misoriented " << boundary.misoriented_edges;
    ASSERT_NEAR(total_volume(mesh), volume, 1e-9 * volume) << "pose " << i;
  }
}

class FullCut : public ::testing::TestWithParam<std::tuple<std::size_t, int>> {};

TEST_P(FullCut, SeparatesIntoPiecesOnEachSideOfTheBlade) {
  if (!std::filesystem::exists(test::data_dir())) {
    GTEST_SKIP() << "no ../shared/data";
  }
  const auto [mesh_index, poses] = GetParam();
  TetMesh mesh = read_tet_mesh(test::data_file(data_meshes()[mesh_index])).mesh;
  const Box box = bounds(mesh);
  const double plane_y = box.low.y() + 0.513 * (box.high.y() - box.low.y());
  int pieces_in = 0;
  (void)tet_components(mesh, &pieces_in);
  const double volume = total_volume(mesh);
  const TetMesh input = mesh;
  cut_checked(mesh, sweep_along_x(box, 0.513, 1.1, poses), poses > 24 ? 8 : 1);
  const Pieces pieces = pieces_across(mesh, plane_y, &input);
  // Separated, in the same way by faces and by vertices.
  EXPECT_GT(pieces.by_faces, pieces_in);
  EXPECT_GE(pieces.by_faces, 2);
  EXPECT_EQ(pieces.by_vertices, pieces.by_faces);
  for (std::size_t p = 0; p < pieces.volumes.size(); ++p) {
    // Every piece lies on one side of the plane the blade swept: nothing still bridges it.
    EXPECT_NE(pieces.sides[p], 0) << "piece " << p << " spans the cut";
    // No shards: a piece is a region the cut enclosed, not a sliver along it (the smallest
    // real piece, an octopus tentacle tip cut twice, is 5.6e-5 of the body).
    EXPECT_GT(pieces.volumes[p], 1e-5 * volume) << "piece " << p << " is a shard";
  }
}

std::string full_cut_name(const ::testing::TestParamInfo<std::tuple<std::size_t, int>>& info) {
  return test::test_name_from(data_meshes()[std::get<0>(info.param)]) + "_" +
         std::to_string(std::get<1>(info.param)) + "_poses";
}

INSTANTIATE_TEST_SUITE_P(DataMeshes, FullCut,
                         ::testing::Combine(::testing::Range<std::size_t>(0, 9),
                                            ::testing::Values(24, 240)),
                         full_cut_name);

TEST(FullCut, SeparatesMeshesMadeFromSurfaces) {
  // Meshes a user makes with `incise mesh` from surfaces in ../shared/data: the SOFA liver's
  // OBJ surface as it is, and the neonatal scalp (STL) remeshed coarse. Full cuts at 24 and
  // 240 poses separate them, valid and conservative after every pose.
  if (!std::filesystem::exists(test::data_dir())) {
    GTEST_SKIP() << "no ../shared/data";
  }
  struct Source {
    const char* file;
    double edge_length;  // surface units; 0: keep the surface
  };
  for (const Source& source :
       {Source{"sofa/liver.obj", 0.0}, Source{"eit-mesher/NNscalp.stl", 12.0}}) {
    TetrahedralizeOptions options;
    if (source.edge_length > 0.0) {
      options.remesh = TetrahedralizeOptions::Remesh::kAlways;
      options.remesh_edge_length = source.edge_length;
    }
    const TetMesh made = tetrahedralize(read_surface(test::data_file(source.file)), options).mesh;
    for (int poses : {24, 240}) {
      SCOPED_TRACE(std::string(source.file) + ", " + std::to_string(poses) + " poses");
      TetMesh mesh = made;
      const Box box = bounds(mesh);
      const double plane_y = box.low.y() + 0.513 * (box.high.y() - box.low.y());
      cut_checked(mesh, sweep_along_x(box, 0.513, 1.1, poses), poses > 24 ? 8 : 1);
      const Pieces pieces = pieces_across(mesh, plane_y, &made);
      EXPECT_GE(pieces.by_faces, 2);
      EXPECT_EQ(pieces.by_vertices, pieces.by_faces);
      for (std::size_t p = 0; p < pieces.volumes.size(); ++p) {
        EXPECT_NE(pieces.sides[p], 0) << "piece " << p << " spans the cut";
      }
    }
  }
}

class PartialCut : public ::testing::TestWithParam<std::size_t> {};

TEST_P(PartialCut, LeavesTheBodyInOnePiece) {
  if (!std::filesystem::exists(test::data_dir())) {
    GTEST_SKIP() << "no ../shared/data";
  }
  TetMesh mesh = read_tet_mesh(test::data_file(data_meshes()[GetParam()])).mesh;
  int pieces_in = 0;
  (void)tet_components(mesh, &pieces_in);
  const int vertex_pieces_in = pieces_by_vertices(mesh);
  // Stops at 45 % of the length: the slit and its crack front, nothing more.
  cut_checked(mesh, sweep_along_x(bounds(mesh), 0.513, 0.45, 40), 1);
  int pieces = 0;
  (void)tet_components(mesh, &pieces);
  EXPECT_EQ(pieces, pieces_in);
  EXPECT_EQ(pieces_by_vertices(mesh), vertex_pieces_in);
}

// Not the octopus: a slit through 45 % of its length severs the tentacles lying there.
INSTANTIATE_TEST_SUITE_P(DataMeshes, PartialCut, ::testing::Range<std::size_t>(0, 8),
                         [](const ::testing::TestParamInfo<std::size_t>& param_info) {
                           return test::test_name_from(data_meshes()[param_info.param]);
                         });

TEST(FullCutGrowth, BarelyDependsOnHowFinelyThePathIsSampled) {
  // The same swept plane in one move, 24 and 240 poses, on every data mesh. Blade-line
  // vertices slide with the blade; one whose face the blade leaves is collapsed onto the point
  // where the cut crosses that face's edge, and one the cut has opened at is collapsed (each
  // side's copy) once the blade has left its face. So what is left is mostly what the swept
  // surface itself needs: the goals, 1.5x (240 against 24 poses) and 2x (against one
  // move), hold on every mesh (before the collapses: up to 2.8x; before opened vertices were
  // collapsed: 1.5x and 2.26x).
  if (!std::filesystem::exists(test::data_dir())) {
    GTEST_SKIP() << "no ../shared/data";
  }
  for (const auto& name : data_meshes()) {
    std::array<std::size_t, 3> tets{};
    const std::array<int, 3> poses{1, 24, 240};
    for (std::size_t k = 0; k < 3; ++k) {
      TetMesh mesh = read_tet_mesh(test::data_file(name)).mesh;
      const double area_in = boundary_area(mesh);
      SubdivisionCutter cutter(mesh);
      cutter.cut_along(sweep_along_x(bounds(mesh), 0.513, 1.1, poses[k]));
      ASSERT_TRUE(validate(mesh).ok()) << name;
      tets[k] = mesh.tet_count();
      // The report's cut area is kept up as faces are found, split, collapsed and given back
      // to shards; a full cut opens every one, adding it twice to the boundary.
      EXPECT_NEAR(cutter.stats().cut_area, (boundary_area(mesh) - area_in) / 2.0, 1e-9 * area_in)
          << name << ", " << poses[k] << " poses";
    }
    const auto ratio = [&](std::size_t a, std::size_t b) {
      return static_cast<double>(tets[a]) / static_cast<double>(tets[b]);
    };
    std::printf("%s: %zu / %zu / %zu tets at 1 / 24 / 240 poses: %.3f x 24 poses, %.3f x one\n",
                name.c_str(), tets[0], tets[1], tets[2], ratio(2, 1), ratio(2, 0));
    EXPECT_LE(ratio(2, 1), 1.5) << name;
    EXPECT_LE(ratio(2, 0), 2.0) << name;
  }
}

TEST(FullCut, StaysValidAtTwoThousandFourHundredPoses) {
  // A blade moved in tiny steps puts blade-line points into the ever thinner tetrahedra it
  // left behind the pose before: on the liver, 5 degenerate tetrahedra at pose 334 until a
  // blade-line point that would thin a tetrahedron below the quality floor was left out.
  if (!std::filesystem::exists(test::data_dir())) {
    GTEST_SKIP() << "no ../shared/data";
  }
  TetMesh mesh = read_tet_mesh(test::data_file("sofa/liver.msh")).mesh;
  const double plane_y = bounds(mesh).low.y() + 0.513 * (bounds(mesh).high - bounds(mesh).low).y();
  const std::size_t tets_in = mesh.tet_count();
  const TetMesh input = mesh;
  cut_checked(mesh, sweep_along_x(bounds(mesh), 0.513, 1.1, 2400), 20);
  const Pieces pieces = pieces_across(mesh, plane_y, &input);
  EXPECT_GE(pieces.by_faces, 2);
  EXPECT_EQ(pieces.by_vertices, pieces.by_faces);
  // Finer sampling than 240 poses adds little: the blade leaves no vertex in slivers.
  EXPECT_LE(mesh.tet_count(), 10 * tets_in);
}

/// A blade that turns as it moves, as a hand (or the viewer's mouse scalpel) turns it: the tip
/// runs along x at `y0`, the base at a y that drifts from `y0` to `y0 + drift` (fractions of
/// the box), so consecutive moves sweep a twisted, curved surface.
std::vector<BladePose> twisting_sweep(const Box& box, double y0, double drift, double depth,
                                      int poses) {
  const Vec3 size = box.high - box.low;
  std::vector<BladePose> path;
  for (int i = 0; i <= poses; ++i) {
    const double s = static_cast<double>(i) / poses;
    const double x = box.low.x() + (-0.1 + 1.2 * s) * size.x();
    const Vec3 tip(x, box.low.y() + y0 * size.y(), box.high.z() - depth * size.z());
    const Vec3 base(x - 0.05 * s * size.x(), box.low.y() + (y0 + drift * s) * size.y(),
                    box.high.z() + 0.2 * size.z());
    path.push_back({0.01 * i, tip, base});
  }
  return path;
}

TEST(TwistingBlade, AFullCutSeparatesAndAPartialCutOpensAlongItsWholeLength) {
  // Until the cut faces of a curved swept surface were allowed to bulge off it a little, a
  // turning blade split the edges it crossed but opened almost none of the faces between
  // them (17 cut faces for a 15 mm mouse stroke on the seed's block).
  BoxGridOptions options;
  options.cells = {4, 6, 4};
  options.size = Vec3(0.04, 0.06, 0.04);
  for (int poses : {30, 120}) {
    SCOPED_TRACE(std::to_string(poses) + " poses");
    TetMesh full = make_box_grid(options);
    cut_checked(full, twisting_sweep(bounds(full), 0.45, 0.05, 1.2, poses), 4);
    const Pieces pieces = pieces_across(full, 0.45 * 0.06);
    EXPECT_EQ(pieces.by_faces, 2);
    EXPECT_EQ(pieces.by_vertices, 2);

    TetMesh partial = make_box_grid(options);
    SubdivisionCutter cutter(partial);
    cutter.cut_along(twisting_sweep(bounds(partial), 0.45, 0.05, 0.5, poses));
    ASSERT_TRUE(validate(partial).ok());
    EXPECT_EQ(pieces_by_vertices(partial), 1);
    // The wound: about 2 cm deep along the 4 cm block, both faces opened.
    EXPECT_GT(cutter.stats().cut_area, 0.8 * 0.04 * 0.02);
  }
}

TEST(SeparateAtCutFaces, OpensABodyAlongAnyCutFacePredicate) {
  // What another cutter (XFEM) reuses: no subdivision cutter here, only a rule for which faces
  // are cut. Faces lying in the plane x = 0.02 of the 4 x 6 x 4-cell block part it in two.
  BoxGridOptions options;
  options.cells = {4, 6, 4};
  options.size = Vec3(0.04, 0.06, 0.04);
  TetMesh mesh = make_box_grid(options);
  const double volume = total_volume(mesh);
  const auto in_plane = [&](TetId tet, int face) {
    for (int k : tet_local::kFaces[face]) {
      if (std::abs(mesh.rest_position(mesh.tet(tet)[k]).x() - 0.02) > 1e-12) {
        return false;
      }
    }
    return true;
  };
  std::vector<VertexId> on_plane;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (std::abs(mesh.rest_position(static_cast<VertexId>(v)).x() - 0.02) < 1e-12) {
      on_plane.push_back(static_cast<VertexId>(v));
    }
  }
  ASSERT_EQ(on_plane.size(), 7u * 5u);
  std::size_t copies = 0;
  for (VertexId v : on_plane) {
    copies += separate_at_cut_faces(mesh, v, in_plane).size();
  }
  EXPECT_EQ(copies, on_plane.size());  // every vertex of the plane, once
  EXPECT_TRUE(validate(mesh).ok());
  EXPECT_NEAR(total_volume(mesh), volume, 1e-15);
  const Pieces pieces = pieces_across(mesh, 0.0);
  EXPECT_EQ(pieces.by_faces, 2);
  EXPECT_EQ(pieces.by_vertices, 2);
  EXPECT_TRUE(pinched_edges(mesh, on_plane, [](VertexId) { return true; }).empty());
  // A predicate that cuts nothing separates nothing.
  EXPECT_TRUE(separate_at_cut_faces(mesh, 0, [](TetId, int) { return false; }).empty());
}

TEST(RandomBladeWalks, KeepEveryInvariantAfterEveryPose) {
  // A fixed number of seeded cuts: a failure names the seed that reproduces it. (Seed 11 left
  // a degenerate tetrahedron at pose 47 while every pose added blade-line vertices.)
  const bool have_data = std::filesystem::exists(test::data_dir());
  for (unsigned seed = 1; seed <= 12; ++seed) {
    std::mt19937 rng(seed);
    TetMesh mesh = walk_mesh(seed, have_data, rng);
    ASSERT_TRUE(validate(mesh).ok()) << "seed " << seed;
    const double volume = total_volume(mesh);
    SCOPED_TRACE("seed " + std::to_string(seed));
    cut_checked(mesh, random_walk(bounds(mesh), rng, 60), 1);
    for (const Vec3& p : mesh.rest_positions()) {
      ASSERT_TRUE(p.allFinite());
    }
    const Pieces pieces = pieces_across(mesh, 0.0);
    EXPECT_EQ(pieces.by_vertices, pieces.by_faces);
    for (double v : pieces.volumes) {
      EXPECT_GT(v, 1e-6 * volume) << "a shard";
    }
  }
}

TEST(CutFaceMarks, FollowATetrahedronAbsorbedByACollapse) {
  // Every boundary face marked as the cut's (as after the cut opened there), then a vertex put
  // in the face between two tetrahedra and collapsed onto a split of that face's edge: the
  // removed tetrahedra's boundary faces pass to the ones that grow over them, so the marked
  // boundary is still the whole boundary (it lost the faces of the absorbed ones before).
  TetMesh mesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.2, 0.3, 1), Vec3(0.3, 0.2, -1)},
               {{0, 1, 2, 3}, {0, 2, 1, 4}});
  CutFaceMarks marks(mesh);
  const auto marked_boundary = [&] {
    double marked = 0.0;
    double all = 0.0;
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      const auto tet = static_cast<TetId>(t);
      for (int f = 0; f < 4; ++f) {
        if (mesh.tet_neighbors(tet)[f] < 0) {
          const auto& local = tet_local::kFaces[static_cast<std::size_t>(f)];
          const Vec3& a = mesh.rest_position(mesh.tet(tet)[local[0]]);
          const double area = 0.5 * (mesh.rest_position(mesh.tet(tet)[local[1]]) - a)
                                        .cross(mesh.rest_position(mesh.tet(tet)[local[2]]) - a)
                                        .norm();
          all += area;
          marked += marks.is_cut(tet, f) ? area : 0.0;
        }
      }
    }
    return std::pair{marked, all};
  };
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    for (int f = 0; f < 4; ++f) {
      if (mesh.tet_neighbors(static_cast<TetId>(t))[f] < 0) {
        marks.mark(static_cast<TetId>(t), f);
      }
    }
  }
  const VertexId in_face = split_face(mesh, 0, mesh.local_index(0, 3), {0.3, 0.3, 0.4});
  const VertexId on_edge = split_edge(mesh, mesh.find_edge(0, 1), 0.4);
  const auto [marked_before, all_before] = marked_boundary();
  ASSERT_NEAR(marked_before, all_before, 1e-14);
  mesh.collapse_vertex(in_face, on_edge);
  ASSERT_TRUE(validate(mesh).ok());
  const auto [marked_after, all_after] = marked_boundary();
  EXPECT_NEAR(all_after, all_before, 1e-14);
  EXPECT_NEAR(marked_after, all_after, 1e-14);
}

}  // namespace
}  // namespace incise
