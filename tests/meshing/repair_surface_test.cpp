// Surface repair: broken surfaces of every kind users bring (holes, flipped, duplicated and
// self-intersecting triangles, non-manifold pieces) become closed, clean surfaces that TetGen
// fills, with every change reported; a clean surface passes untouched; what a mode does not
// allow is refused naming what is left.

#include "incise/meshing/repair_surface.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "incise/core/error.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/meshing/tetrahedralize.hpp"
#include "test_support.hpp"
#include "test_surfaces.hpp"

namespace incise {
namespace {

using test::append_surface;
using test::box_surface;
using test::enclosed_volume;
using Mode = SurfaceRepairOptions::Mode;

SurfaceMesh repaired(const SurfaceMesh& surface, Mode mode, SurfaceRepairReport& report) {
  SurfaceRepairOptions options;
  options.mode = mode;
  return repair_surface(surface, options, report);
}

/// The repaired surface is closed and clean, and TetGen fills it with a valid mesh of the
/// volume it bounds.
void expect_fillable(const SurfaceMesh& surface) {
  const SurfaceCheckReport check = check_closed_surface(surface);
  ASSERT_TRUE(check.ok()) << check.describe();
  const TetrahedralizeResult result = tetrahedralize(surface);
  EXPECT_TRUE(validate(result.mesh).ok());
  EXPECT_NEAR(total_volume(result.mesh), enclosed_volume(surface), 1e-7 * enclosed_volume(surface));
}

TEST(RepairSurface, ACleanSurfacePassesUntouched) {
  const SurfaceMesh box = box_surface();
  SurfaceRepairReport report;
  const SurfaceMesh same = repaired(box, Mode::kAuto, report);
  EXPECT_FALSE(report.changed);
  EXPECT_TRUE(report.notes.empty());
  EXPECT_EQ(same.points, box.points);
  EXPECT_EQ(same.triangles, box.triangles);
}

TEST(RepairSurface, HolesAreFilledAndTheirAreaSaid) {
  SurfaceMesh box = box_surface();
  // Two holes apart: the first triangle and one that shares no point with it. Each is half
  // a 0.5 x 0.5 cell of the unit box's 2 x 2 faces.
  const Triangle first = box.triangles.front();
  std::size_t apart = 1;
  const auto shares = [&](const Triangle& t) {
    for (VertexId v : t) {
      if (std::find(first.begin(), first.end(), v) != first.end()) {
        return true;
      }
    }
    return false;
  };
  while (shares(box.triangles[apart])) {
    ++apart;
  }
  box.triangles.erase(box.triangles.begin() + static_cast<std::ptrdiff_t>(apart));
  box.triangles.erase(box.triangles.begin());
  ASSERT_FALSE(check_closed_surface(box).ok());
  SurfaceRepairReport report;
  const SurfaceMesh fixed = repaired(box, Mode::kInPlace, report);
  EXPECT_TRUE(report.changed);
  EXPECT_FALSE(report.wrapped);
  EXPECT_EQ(report.holes_filled, 2u);
  EXPECT_NEAR(report.hole_area, 2 * 0.125, 1e-9);
  EXPECT_NEAR(report.largest_hole_area, 0.125, 1e-9);
  EXPECT_NEAR(enclosed_volume(fixed), 1.0, 1e-9);  // the holes were flat: nothing bulges
  EXPECT_LT(report.result_to_input, 1e-9);
  expect_fillable(fixed);
}

TEST(RepairSurface, FlippedTrianglesAndAnInsideOutSurfaceAreTurned) {
  SurfaceMesh box = box_surface();
  for (const int t : {2, 7, 11}) {
    std::swap(box.triangles[static_cast<std::size_t>(t)][0],
              box.triangles[static_cast<std::size_t>(t)][1]);
  }
  SurfaceRepairReport report;
  expect_fillable(repaired(box, Mode::kInPlace, report));
  EXPECT_NEAR(enclosed_volume(repaired(box, Mode::kInPlace, report)), 1.0, 1e-9);
  // Every triangle the wrong way round: the whole surface faces in.
  SurfaceMesh inside_out = box_surface();
  for (Triangle& t : inside_out.triangles) {
    std::swap(t[0], t[1]);
  }
  const SurfaceMesh turned = repaired(inside_out, Mode::kInPlace, report);
  EXPECT_TRUE(report.reoriented);
  EXPECT_NEAR(enclosed_volume(turned), 1.0, 1e-9);
}

TEST(RepairSurface, AnOpenDomeLikeAFaceScanIsCappedIntoASolid) {
  // A scan is a sheet: a unit hemisphere of 12 rings x 32 sectors, open at its rim. Its rim
  // is filled (a flat cap), and the solid is the half ball.
  SurfaceMesh dome;
  constexpr int kRings = 12;
  constexpr int kSectors = 32;
  dome.points.emplace_back(0, 0, 1);
  for (int ring = 1; ring <= kRings; ++ring) {
    const double polar = 0.5 * std::numbers::pi * ring / kRings;
    for (int sector = 0; sector < kSectors; ++sector) {
      const double azimuth = 2.0 * std::numbers::pi * sector / kSectors;
      dome.points.emplace_back(std::sin(polar) * std::cos(azimuth),
                               std::sin(polar) * std::sin(azimuth), std::cos(polar));
    }
  }
  const auto at = [](int ring, int sector) {
    return static_cast<VertexId>(1 + (ring - 1) * kSectors + sector % kSectors);
  };
  for (int sector = 0; sector < kSectors; ++sector) {
    dome.triangles.push_back({0, at(1, sector), at(1, sector + 1)});
  }
  for (int ring = 1; ring < kRings; ++ring) {
    for (int sector = 0; sector < kSectors; ++sector) {
      dome.triangles.push_back({at(ring, sector), at(ring + 1, sector), at(ring + 1, sector + 1)});
      dome.triangles.push_back({at(ring, sector), at(ring + 1, sector + 1), at(ring, sector + 1)});
    }
  }
  SurfaceRepairReport report;
  const SurfaceMesh solid = repaired(dome, Mode::kAuto, report);
  EXPECT_FALSE(report.wrapped);
  EXPECT_EQ(report.holes_filled, 1u);
  // The cap is the rim's polygon: 32 sides on the unit circle.
  EXPECT_NEAR(report.hole_area, 16.0 * std::sin(2.0 * std::numbers::pi / kSectors), 1e-9);
  EXPECT_LT(report.input_to_result, 1e-12);  // the sheet itself is kept
  EXPECT_NEAR(enclosed_volume(solid), 2.0 * std::numbers::pi / 3.0, 0.05);
  expect_fillable(solid);
}

TEST(RepairSurface, DuplicatedPointsAndTrianglesAreMergedAndRemoved) {
  SurfaceMesh box = box_surface();
  // Every triangle twice, and its own copy of each point (as an STL file stores them).
  SurfaceMesh soup;
  for (const Triangle& t : box.triangles) {
    for (int copy = 0; copy < 2; ++copy) {
      const auto first = static_cast<VertexId>(soup.points.size());
      for (VertexId v : t) {
        soup.points.push_back(box.points[static_cast<std::size_t>(v)]);
      }
      soup.triangles.push_back({first, first + 1, first + 2});
    }
  }
  SurfaceRepairReport report;
  const SurfaceMesh fixed = repaired(soup, Mode::kInPlace, report);
  EXPECT_EQ(report.triangles_removed, box.triangles.size());
  EXPECT_EQ(fixed.triangles.size(), box.triangles.size());
  EXPECT_EQ(fixed.points.size(), box.points.size() - 1);  // less the box grid's middle point
  expect_fillable(fixed);
}

TEST(RepairSurface, TwoBoxesTouchingAtACornerBecomeOneClosedSurface) {
  // Two closed boxes sharing one corner point: a non-manifold vertex. Split, its two copies
  // would still touch (TetGen cannot take that), so the wrap closes it.
  SurfaceMesh surface = box_surface();
  append_surface(surface, box_surface(Vec3(1, 1, 1)));
  SurfaceRepairReport report;
  const SurfaceMesh fixed = repaired(surface, Mode::kAuto, report);
  EXPECT_TRUE(check_closed_surface(fixed).ok());
  EXPECT_NEAR(enclosed_volume(fixed), 2.0, 0.1);
  EXPECT_LE(report.result_to_input, 2.0 * report.offset);
}

TEST(RepairSurface, SelfIntersectionsAreWrappedWithinTheStatedOffset) {
  // Two overlapping closed boxes in one surface: no repair in place makes that a boundary.
  SurfaceMesh surface = box_surface();
  append_surface(surface, box_surface(Vec3(0.5, 0.5, 0.5)));
  SurfaceRepairReport report;
  try {
    (void)repaired(surface, Mode::kInPlace, report);
    FAIL() << "in place only, overlapping boxes cannot become one boundary";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("self-intersection"), std::string::npos)
        << error.what();
    EXPECT_NE(std::string(error.what()).find("--repair auto"), std::string::npos);
  }
  const SurfaceMesh wrapped = repaired(surface, Mode::kAuto, report);
  EXPECT_TRUE(report.wrapped);
  EXPECT_GT(report.offset, 0.0);
  // The union of the two boxes is 2 - 0.125 = 1.875; the wrap lies about the offset outside
  // it (and rounds its edges within alpha), so its volume is a little larger.
  const double volume = enclosed_volume(wrapped);
  EXPECT_GT(volume, 1.875);
  EXPECT_LT(volume, 1.875 * 1.1);
  // Every point of the wrap lies near the input (the input's inner parts, inside the union,
  // lie far from the wrap: that distance says nothing here).
  EXPECT_LE(report.result_to_input, 2.0 * report.offset);
  expect_fillable(wrapped);
}

TEST(RepairSurface, NoneRefusesAndSaysWhatWouldRepairIt) {
  SurfaceMesh box = box_surface();
  box.triangles.pop_back();
  SurfaceRepairReport report;
  try {
    (void)repaired(box, Mode::kNone, report);
    FAIL();
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("open edges"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("--repair"), std::string::npos) << error.what();
  }
}

TEST(RepairSurface, RefusedDataSurfacesBecomeBodies) {
  // Two surfaces of ../shared/data that TetGen refuses as they are: SOFA's smooth liver (self-
  // intersecting) and the neonatal skull (an edge on four triangles).
  for (const char* name : {"sofa/liver-smooth.obj", "eit-mesher/NNskull_lowpoly.STL"}) {
    const SurfaceMesh surface = read_surface(test::data_file(name));
    ASSERT_FALSE(check_closed_surface(surface).ok()) << name;
    SurfaceRepairReport report;
    SurfaceRepairOptions options;
    options.wrap_alpha = 0.0;
    const SurfaceMesh fixed = repair_surface(surface, options, report);
    EXPECT_TRUE(report.changed) << name;
    EXPECT_TRUE(check_closed_surface(fixed).ok()) << name;
    EXPECT_GT(enclosed_volume(fixed), 0.0) << name;
    EXPECT_LE(report.result_to_input, 2.0 * report.offset) << name;
  }
}

}  // namespace
}  // namespace incise
