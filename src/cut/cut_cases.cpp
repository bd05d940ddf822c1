#include "incise/cut/cut_cases.hpp"

#include <algorithm>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {

const char* cut_case_name(CutCase kind) {
  switch (kind) {
    case CutCase::kNone:
      return "none";
    case CutCase::kA:
      return "A";
    case CutCase::kB:
      return "B";
    case CutCase::kC:
      return "C";
    case CutCase::kD:
      return "D";
    case CutCase::kE:
      return "E";
    case CutCase::kInvalid:
      break;
  }
  return "invalid";
}

std::uint8_t canonical_edge_code(CutCase kind) {
  // Edge bits in tet_local::kEdges order: 01, 02, 03, 12, 13, 23.
  switch (kind) {
    case CutCase::kA:
      return 0b000111;  // 01 02 03: vertex 0 cut off
    case CutCase::kB:
      return 0b011110;  // 02 03 12 13: {0,1} from {2,3}
    case CutCase::kC:
      return 0b000001;  // 01
    case CutCase::kD:
      return 0b000011;  // 01 02: two edges of face 012
    case CutCase::kE:
      return 0b001110;  // 02 03 12: three edges of B's quad
    default:
      return 0;
  }
}

std::uint8_t permute_edge_code(std::uint8_t code, const std::array<std::uint8_t, 4>& permutation) {
  std::uint8_t result = 0;
  for (int k = 0; k < 6; ++k) {
    if ((code >> k & 1U) == 0) {
      continue;
    }
    const int a = permutation[static_cast<std::size_t>(tet_local::kEdges[k][0])];
    const int b = permutation[static_cast<std::size_t>(tet_local::kEdges[k][1])];
    for (int m = 0; m < 6; ++m) {
      const auto& e = tet_local::kEdges[m];
      if ((e[0] == a && e[1] == b) || (e[0] == b && e[1] == a)) {
        result = static_cast<std::uint8_t>(result | (1U << m));
      }
    }
  }
  return result;
}

const std::array<CutCaseEntry, 128>& cut_case_table() {
  static const std::array<CutCaseEntry, 128> table = [] {
    std::array<CutCaseEntry, 128> entries{};
    entries[cut_state_key(0, false)] = {CutCase::kNone, {0, 1, 2, 3}};
    entries[cut_state_key(0, true)] = {CutCase::kNone, {0, 1, 2, 3}};
    std::array<std::uint8_t, 4> permutation{0, 1, 2, 3};
    do {
      // Full cuts separate the tetrahedron: A and B. While the blade is still inside, the same
      // codes are the unfinished A and B; slits C, D and E exist only as partial cuts.
      for (CutCase kind : {CutCase::kA, CutCase::kB}) {
        const std::uint8_t code = permute_edge_code(canonical_edge_code(kind), permutation);
        for (bool partial : {false, true}) {
          CutCaseEntry& entry = entries[cut_state_key(code, partial)];
          if (entry.kind == CutCase::kInvalid) {
            entry = {kind, permutation};
          }
        }
      }
      for (CutCase kind : {CutCase::kC, CutCase::kD, CutCase::kE}) {
        CutCaseEntry& entry =
            entries[cut_state_key(permute_edge_code(canonical_edge_code(kind), permutation), true)];
        if (entry.kind == CutCase::kInvalid) {
          entry = {kind, permutation};
        }
      }
    } while (std::next_permutation(permutation.begin(), permutation.end()));
    return entries;
  }();
  return table;
}

}  // namespace incise
