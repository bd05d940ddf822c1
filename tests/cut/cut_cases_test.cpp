// The case table against a brute-force classification of every cut state.

#include "incise/cut/cut_cases.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <map>

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
