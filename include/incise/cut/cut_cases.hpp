#pragma once
// The seed's cut cases (section 4.1): a tetrahedron cut in one incision shows one of five
// topologies. A and B are full cuts (a vertex or an edge pair separated, as in marching
// tetrahedra); C, D and E are slits with one, two and three cut edges. The key is the 6-bit
// cut-edge code (bit k: tet_local::kEdges[k] is cut) plus whether the cut is still partial.
// The table is generated here from one canonical entry per case by the 24 vertex permutations
// (rotations and mirrors), not typed by hand.

#include <array>
#include <cstdint>

namespace incise {

enum class CutCase : std::uint8_t { kNone, kA, kB, kC, kD, kE, kInvalid };

[[nodiscard]] const char* cut_case_name(CutCase kind);

/// One state of a tetrahedron's cut: its case (A-E of the seed) and how the case's canonical
/// tetrahedron maps onto it.
struct CutCaseEntry {
  CutCase kind = CutCase::kInvalid;  ///< the seed's case, or kInvalid for a state none matches
  /// Vertex permutation taking the case's canonical tetrahedron to this one:
  /// canonical vertex i is this tetrahedron's vertex permutation[i].
  std::array<std::uint8_t, 4> permutation{0, 1, 2, 3};
};

/// Index of a cut state in the table: the edge code, plus 64 when the cut is partial.
[[nodiscard]] constexpr std::size_t cut_state_key(std::uint8_t edge_code, bool partial) {
  return static_cast<std::size_t>(edge_code & 63U) + (partial ? 64U : 0U);
}

/// The 128-entry table keyed by cut_state_key.
[[nodiscard]] const std::array<CutCaseEntry, 128>& cut_case_table();

/// The canonical edge code of a case (vertex 0 cut off for A, {0,1} from {2,3} for B, edge 01
/// for C, edges 01 and 02 for D, edges 02, 03 and 12 for E).
[[nodiscard]] std::uint8_t canonical_edge_code(CutCase kind);

/// The edge code after relabelling vertex i as permutation[i].
[[nodiscard]] std::uint8_t permute_edge_code(std::uint8_t code,
                                             const std::array<std::uint8_t, 4>& permutation);

}  // namespace incise
