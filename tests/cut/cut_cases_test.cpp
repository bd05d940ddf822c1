// The case table against a brute-force classification of every cut state.

#include "incise/cut/cut_cases.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <map>

#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {
namespace {

/// Classifies a cut state from first principles: which vertex sets the cut edges separate.
CutCase brute_force(std::uint8_t code, bool partial) {
  const int bits = std::popcount(static_cast<unsigned>(code));
  if (bits == 0) {
    return CutCase::kNone;
  }
  // Full separation: some vertex set S (not empty, not all) such that the cut edges are exactly
  // the edges between S and its complement.
  for (unsigned subset = 1; subset < 15; ++subset) {
    std::uint8_t boundary = 0;
    for (int k = 0; k < 6; ++k) {
      const bool a = (subset >> tet_local::kEdges[k][0] & 1U) != 0;
      const bool b = (subset >> tet_local::kEdges[k][1] & 1U) != 0;
      if (a != b) {
        boundary = static_cast<std::uint8_t>(boundary | 1U << k);
      }
    }
    if (boundary == code) {
      return std::popcount(subset) == 2 ? CutCase::kB : CutCase::kA;
    }
  }
  if (!partial) {
    return CutCase::kInvalid;  // a finished cut always separates
  }
  // Slits: edges a partial planar cut can cross. Two edges must share a vertex (a face);
  // three must be three edges of a separating quad.
  if (bits == 1) {
    return CutCase::kC;
  }
  auto edges_share_vertex = [](int x, int y) {
    const auto& a = tet_local::kEdges[x];
    const auto& b = tet_local::kEdges[y];
    return a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1];
  };
  if (bits == 2) {
    int first = std::countr_zero(static_cast<unsigned>(code));
    int second = std::countr_zero(static_cast<unsigned>(code) & ~(1U << first));
    return edges_share_vertex(first, second) ? CutCase::kD : CutCase::kInvalid;
  }
  if (bits == 3) {
    for (unsigned subset : {3U, 5U, 6U}) {  // the three vertex pairings {01|23}, {02|13}, {12|03}
      std::uint8_t quad = 0;
      for (int k = 0; k < 6; ++k) {
        if (((subset >> tet_local::kEdges[k][0]) & 1U) !=
            ((subset >> tet_local::kEdges[k][1]) & 1U)) {
          quad = static_cast<std::uint8_t>(quad | 1U << k);
        }
      }
      if ((code & ~quad) == 0) {
        return CutCase::kE;
      }
    }
  }
  return CutCase::kInvalid;
}

TEST(CutCases, TableMatchesBruteForceForEveryState) {
  const auto& table = cut_case_table();
  for (unsigned code = 0; code < 64; ++code) {
    for (bool partial : {false, true}) {
      const CutCaseEntry& entry = table[cut_state_key(static_cast<std::uint8_t>(code), partial)];
      EXPECT_EQ(entry.kind, brute_force(static_cast<std::uint8_t>(code), partial))
          << "code " << code << (partial ? " partial" : " full");
      if (entry.kind != CutCase::kInvalid && entry.kind != CutCase::kNone) {
        // The stored permutation maps the canonical case onto this very code.
        EXPECT_EQ(permute_edge_code(canonical_edge_code(entry.kind), entry.permutation), code);
      }
    }
  }
}

TEST(CutCases, SubcaseCountsMatchTheSeed) {
  // "four different subcases for A, three for B, and six for C ... 12 combinations each for
  // ... case D and ... case E" (seed section 4.1).
  std::map<CutCase, int> full;
  std::map<CutCase, int> partial;
  for (unsigned code = 1; code < 64; ++code) {
    ++full[cut_case_table()[cut_state_key(static_cast<std::uint8_t>(code), false)].kind];
    ++partial[cut_case_table()[cut_state_key(static_cast<std::uint8_t>(code), true)].kind];
  }
  EXPECT_EQ(full[CutCase::kA], 4);
  EXPECT_EQ(full[CutCase::kB], 3);
  EXPECT_EQ(partial[CutCase::kC], 6);
  EXPECT_EQ(partial[CutCase::kD], 12);
  EXPECT_EQ(partial[CutCase::kE], 12);
  EXPECT_EQ(full[CutCase::kInvalid], 63 - 7);
}

TEST(CutCases, PermutingEdgeCodes) {
  // Swapping vertices 0 and 1 keeps edge 01 and swaps 02 <-> 12, 03 <-> 13.
  const std::array<std::uint8_t, 4> swap01{1, 0, 2, 3};
  EXPECT_EQ(permute_edge_code(0b000001, swap01), 0b000001);
  EXPECT_EQ(permute_edge_code(0b000010, swap01), 0b001000);
  EXPECT_EQ(permute_edge_code(0b000100, swap01), 0b010000);
  EXPECT_EQ(permute_edge_code(0b100000, swap01), 0b100000);
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(CutCases, CodesAccumulateOnTheOriginalTetrahedraAcrossMoves) {
  // A vertical blade swept in many small moves through the plane x = 0.37 of a 2 x 2 x 2 grid
  // (cells 0.5 m): every crossing lies inside an original edge (fraction 0.74, not snapped), so
  // each original tetrahedron of the first column ends with a complete cut, case A (three edges:
  // one corner cut off) or B (four edges: two and two), built up move by move.
  BoxGridOptions grid;
  grid.cells = {2, 2, 2};
  TetMesh mesh = make_box_grid(grid);
  const std::size_t originals = mesh.tet_count();
  SubdivisionCutter cutter(mesh);
  std::vector<BladePose> path;
  for (int i = 0; i <= 40; ++i) {
    const double y = -0.1 + 1.2 * i / 40.0;
    path.push_back({0.025 * i, Vec3(0.37, y, -0.1), Vec3(0.37, y, 1.1)});
  }
  cutter.start(path.front());
  std::size_t partial_seen = 0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    cutter.move_to(path[i]);
    const auto counts = cutter.accumulated_case_counts();
    partial_seen += counts[static_cast<std::size_t>(CutCase::kC)] +
                    counts[static_cast<std::size_t>(CutCase::kD)] +
                    counts[static_cast<std::size_t>(CutCase::kE)];
  }
  const auto counts = cutter.accumulated_case_counts();
  const std::size_t complete =
      counts[static_cast<std::size_t>(CutCase::kA)] + counts[static_cast<std::size_t>(CutCase::kB)];
  EXPECT_EQ(counts[static_cast<std::size_t>(CutCase::kInvalid)], 0u);
  EXPECT_EQ(counts[static_cast<std::size_t>(CutCase::kC)] +
                counts[static_cast<std::size_t>(CutCase::kD)] +
                counts[static_cast<std::size_t>(CutCase::kE)],
            0u);
  // The first column (x in [0, 0.5]) holds half the tetrahedra; each is crossed by the plane.
  EXPECT_EQ(complete, originals / 2);
  EXPECT_GT(counts[static_cast<std::size_t>(CutCase::kA)], 0u);
  EXPECT_GT(counts[static_cast<std::size_t>(CutCase::kB)], 0u);
  EXPECT_GT(partial_seen, 0u) << "tetrahedra the blade was inside were never partial";
  std::size_t cut_originals = 0;
  for (std::uint8_t code : cutter.accumulated_codes()) {
    cut_originals += code != 0 ? 1 : 0;
  }
  EXPECT_EQ(cut_originals, originals / 2);
  // Children keep at least the snap fraction of their parent; against the original the bound
  // compounds, but stays positive.
  EXPECT_GT(cutter.min_volume_ratio_to_original(), 0.0);
  EXPECT_LE(cutter.min_volume_ratio_to_original(), cutter.stats().min_volume_ratio + 1e-12);
}

}  // namespace
}  // namespace incise
