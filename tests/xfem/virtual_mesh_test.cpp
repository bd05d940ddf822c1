// The XFEM body: a full cut separates it into pieces whose material volumes are the exactly
// clipped ones, a partial cut keeps it whole with its front tied, and no rest element is ever
// created.

#include "incise/xfem/virtual_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>

#include "incise/cut/blade.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/generators.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

std::array<Vec3, 4> corners(const TetMesh& mesh, TetId t) {
  const Tet& tet = mesh.tet(t);
  return {mesh.rest_position(tet[0]), mesh.rest_position(tet[1]), mesh.rest_position(tet[2]),
          mesh.rest_position(tet[3])};
}

/// The cut of every tetrahedron by the plane x = `at`; those `keep` rejects become the front.
struct PlaneCut {
  std::vector<std::optional<ElementCut>> cuts;
  std::vector<TetId> front;
};
template <typename Keep>
PlaneCut cut_at(const TetMesh& mesh, double at, Keep keep) {
  PlaneCut result;
  result.cuts.resize(mesh.tet_count());
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto cut =
        cut_by_plane(corners(mesh, static_cast<TetId>(t)), Vec3(at, 0, 0), Vec3::UnitX());
    if (!cut) {
      continue;
    }
    if (keep(corners(mesh, static_cast<TetId>(t)))) {
      result.cuts[t] = cut;
    } else {
      result.front.push_back(static_cast<TetId>(t));
    }
  }
  return result;
}

TEST(VirtualMesh, AFullCutSeparatesTheBarIntoTheClippedPieces) {
  const TetMesh mesh = test::bar_8x2x2cm();
  const PlaneCut plane = cut_at(mesh, 0.0437, [](const auto&) { return true; });
  const VirtualMesh body = build_virtual_mesh(mesh, plane.cuts);
  EXPECT_GT(body.split, 0u);
  EXPECT_EQ(body.tied, 0u);
  EXPECT_EQ(body.elements.size(), mesh.tet_count() + body.split);
  // No new rest element: every element integrates over one of the mesh's tetrahedra, a split
  // one exactly twice with fractions summing to one.
  std::map<TetId, double> fractions;
  for (std::size_t e = 0; e < body.elements.size(); ++e) {
    ASSERT_LT(static_cast<std::size_t>(body.rest_tet[e]), mesh.tet_count());
    fractions[body.rest_tet[e]] += body.fraction[e];
  }
  EXPECT_EQ(fractions.size(), mesh.tet_count());
  for (const auto& [tet, sum] : fractions) {
    EXPECT_NEAR(sum, 1.0, 1e-14) << tet;
  }
  const double total = 0.08 * 0.02 * 0.02;
  EXPECT_NEAR(material_volume(body, mesh), total, 1e-15);
  // Two pieces, of the volumes the plane clips.
  int count = 0;
  const std::vector<int> pieces = virtual_pieces(body, &count);
  ASSERT_EQ(count, 2);
  std::array<double, 2> volume{};
  std::array<double, 2> centre_x{};
  for (std::size_t e = 0; e < body.elements.size(); ++e) {
    const auto x = corners(mesh, body.rest_tet[e]);
    const double v = body.fraction[e] * signed_volume(mesh, body.rest_tet[e]);
    volume[static_cast<std::size_t>(pieces[e])] += v;
    centre_x[static_cast<std::size_t>(pieces[e])] += v * (x[0] + x[1] + x[2] + x[3]).x() / 4.0;
  }
  const std::size_t left = centre_x[0] / volume[0] < centre_x[1] / volume[1] ? 0 : 1;
  EXPECT_NEAR(volume[left], 0.0437 * 0.02 * 0.02, 1e-15);
  EXPECT_NEAR(volume[1 - left], (0.08 - 0.0437) * 0.02 * 0.02, 1e-15);
  // Copies stand where their originals are, and only vertices of split tetrahedra have one.
  for (std::size_t v = body.first_copy; v < body.rest_positions.size(); ++v) {
    EXPECT_EQ(body.rest_positions[v], mesh.rest_position(body.original_of[v]));
  }
  EXPECT_EQ(body.dofs_added(), 3 * body.copies());
}

TEST(VirtualMesh, APartialCutStaysWholeWithItsFrontTied) {
  const TetMesh mesh = test::bar_8x2x2cm();
  // The blade went down to mid-height: tetrahedra in the lower cell layer are crossed
  // completely; those above it are reached but not crossed (the front).
  const PlaneCut plane = cut_at(mesh, 0.0437, [](const std::array<Vec3, 4>& x) {
    return std::max({x[0].z(), x[1].z(), x[2].z(), x[3].z()}) < 0.0101;
  });
  ASSERT_FALSE(plane.front.empty());
  const VirtualMesh body = build_virtual_mesh(mesh, plane.cuts, plane.front);
  EXPECT_GT(body.split, 0u);
  EXPECT_GT(body.tied, 0u);
  EXPECT_GT(body.copies(), 0u);  // below the front the cut is open
  // At the front it is closed: no copy of an end of a crossed edge a front tetrahedron holds.
  std::set<VertexId> front_ends;
  for (TetId t : plane.front) {
    const Tet& tet = mesh.tet(t);
    for (const auto& edge : tet_local::kEdges) {
      const VertexId i = tet[static_cast<std::size_t>(edge[0])];
      const VertexId j = tet[static_cast<std::size_t>(edge[1])];
      if ((mesh.rest_position(i).x() < 0.0437) != (mesh.rest_position(j).x() < 0.0437)) {
        front_ends.insert(i);
        front_ends.insert(j);
      }
    }
  }
  ASSERT_FALSE(front_ends.empty());
  for (std::size_t v = body.first_copy; v < body.rest_positions.size(); ++v) {
    EXPECT_FALSE(front_ends.contains(body.original_of[v])) << body.original_of[v];
  }
  int count = 0;
  (void)virtual_pieces(body, &count);
  EXPECT_EQ(count, 1);
  EXPECT_NEAR(material_volume(body, mesh), 0.08 * 0.02 * 0.02, 1e-15);
}

/// A vertical blade (from below the bar to above it) at x = 0.0437 swept along y from
/// outside the bar to `to_y`, in 12 poses.
std::vector<std::array<Vec3, 3>> blade_sweep(double to_y) {
  std::vector<BladePose> poses;
  for (int i = 0; i <= 12; ++i) {
    const double y = -0.01 + (to_y + 0.01) * i / 12.0;
    poses.push_back({0.1 * i, Vec3(0.0437, y, -0.01), Vec3(0.0437, y + 0.001 * (i % 2), 0.03)});
  }
  std::vector<std::array<Vec3, 3>> triangles;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    for (const auto& triangle : swept_triangles(poses[i - 1], poses[i])) {
      triangles.push_back(triangle);
    }
  }
  return triangles;
}

TEST(VirtualMesh, ABladeSweptThroughSeparatesAndOneSweptHalfWayDoesNot) {
  const TetMesh mesh = test::bar_8x2x2cm();
  const double total = 0.08 * 0.02 * 0.02;
  {
    const SurfaceCuts through = cuts_by_surface(mesh, blade_sweep(0.03));
    const VirtualMesh body = build_virtual_mesh(mesh, through.cuts, through.front);
    int count = 0;
    (void)virtual_pieces(body, &count);
    EXPECT_EQ(count, 2);
    EXPECT_TRUE(through.front.empty());
    EXPECT_NEAR(material_volume(body, mesh), total, 1e-15);
  }
  {
    const SurfaceCuts half = cuts_by_surface(mesh, blade_sweep(0.011));
    EXPECT_FALSE(half.front.empty());
    const VirtualMesh body = build_virtual_mesh(mesh, half.cuts, half.front);
    EXPECT_GT(body.split, 0u);
    EXPECT_GT(body.tied, 0u);
    int count = 0;
    (void)virtual_pieces(body, &count);
    EXPECT_EQ(count, 1);
    EXPECT_NEAR(material_volume(body, mesh), total, 1e-15);
  }
}

TEST(VirtualMesh, AFullCutSeparatesRealMeshes) {
  // The full cut of issue "Cut real anatomy right": a vertical blade from below to above the
  // body, swept along x across it at 0.513 of its y-extent, in 25 poses.
  int meshes = 0;
  for (const char* name : {"sofa/liver.msh", "sofa-mor/liverCoarse.vtu", "pbd/armadillo_4k.node",
                           "sofa/cylinder.msh", "libigl/octopus-low.mesh"}) {
    const auto path = test::data_file(name);
    if (!std::filesystem::exists(path)) {
      continue;
    }
    ++meshes;
    const TetMesh mesh = read_tet_mesh(path).mesh;
    Vec3 low = mesh.rest_position(0);
    Vec3 high = low;
    for (const Vec3& p : mesh.rest_positions()) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
    const Vec3 margin = 0.05 * (high - low);
    const double y = low.y() + 0.513 * (high.y() - low.y());
    std::vector<BladePose> poses;
    for (int i = 0; i <= 24; ++i) {
      const double x = low.x() - margin.x() + (high.x() - low.x() + 2 * margin.x()) * i / 24.0;
      poses.push_back(
          {0.04 * i, Vec3(x, y, low.z() - margin.z()), Vec3(x, y, high.z() + margin.z())});
    }
    std::vector<std::array<Vec3, 3>> triangles;
    for (std::size_t i = 1; i < poses.size(); ++i) {
      for (const auto& triangle : swept_triangles(poses[i - 1], poses[i])) {
        triangles.push_back(triangle);
      }
    }
    const SurfaceCuts cuts = cuts_by_surface(mesh, triangles);
    const VirtualMesh body = build_virtual_mesh(mesh, cuts.cuts, cuts.front);
    EXPECT_GT(body.split, 0u) << name;
    EXPECT_TRUE(cuts.front.empty()) << name;  // the surface crosses the whole body
    const double rest = total_volume(mesh);
    EXPECT_NEAR(material_volume(body, mesh), rest, 1e-12 * rest) << name;
    for (double fraction : body.fraction) {
      EXPECT_GE(fraction, 0.0);
      EXPECT_LE(fraction, 1.0);
    }
    int count = 0;
    const std::vector<int> pieces = virtual_pieces(body, &count);
    EXPECT_GE(count, 2) << name;
    // No piece straddles the cut plane: every element lies (by its material's side) on one.
    std::map<int, std::pair<double, double>> extent;  // piece -> min, max of element centroids' y
    for (std::size_t e = 0; e < body.elements.size(); ++e) {
      if (pieces[e] < 0 || body.fraction[e] < 1e-6) {
        continue;
      }
      Vec3 centre = Vec3::Zero();
      for (VertexId v : mesh.tet(body.rest_tet[e])) {
        centre += mesh.rest_position(v) / 4.0;
      }
      if (body.fraction[e] == 1.0) {
        auto [it, added] = extent.try_emplace(pieces[e], centre.y(), centre.y());
        it->second.first = std::min(it->second.first, centre.y());
        it->second.second = std::max(it->second.second, centre.y());
      }
    }
    for (const auto& [piece, range] : extent) {
      EXPECT_FALSE(range.first < y && range.second > y) << name << " piece " << piece;
    }
    std::printf("%s: %zu tets, %zu split, %zu copies, %d pieces\n", name, mesh.tet_count(),
                body.split, body.copies(), count);
  }
  if (meshes == 0) {
    GTEST_SKIP() << "no data meshes";
  }
}

TEST(VirtualMesh, AMinimumFractionKeepsElementsFromEmptyingAndConservesMaterial) {
  // A plane 1e-6 m past a grid plane of the bar: slivers of fraction about 1e-4 and below.
  const TetMesh mesh = test::bar_8x2x2cm();
  const PlaneCut plane = cut_at(mesh, 0.04 + 1e-6, [](const auto&) { return true; });
  const VirtualMesh exact = build_virtual_mesh(mesh, plane.cuts);
  const VirtualMesh conditioned = build_virtual_mesh(mesh, plane.cuts, {}, 1e-3);
  EXPECT_LT(*std::min_element(exact.fraction.begin(), exact.fraction.end()), 1e-3);
  EXPECT_GE(*std::min_element(conditioned.fraction.begin(), conditioned.fraction.end()),
            1e-3 - 1e-15);
  EXPECT_GT(conditioned.raised, 0u);
  EXPECT_EQ(exact.raised, 0u);
  const double total = 0.08 * 0.02 * 0.02;
  EXPECT_NEAR(material_volume(exact, mesh), total, 1e-15);
  EXPECT_NEAR(material_volume(conditioned, mesh), total, 1e-15);
  int count = 0;
  (void)virtual_pieces(conditioned, &count);
  EXPECT_EQ(count, 2);
}

TEST(VirtualMesh, NoCutNoChange) {
  const TetMesh mesh = test::bar_8x2x2cm();
  const std::vector<std::optional<ElementCut>> none(mesh.tet_count());
  const VirtualMesh body = build_virtual_mesh(mesh, none);
  EXPECT_EQ(body.elements.size(), mesh.tet_count());
  EXPECT_EQ(body.copies(), 0u);
  int count = 0;
  (void)virtual_pieces(body, &count);
  EXPECT_EQ(count, 1);
}

}  // namespace
}  // namespace incise
