#include "incise/mesh/validate.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <sstream>

#include "incise/core/parallel_for.hpp"
#include "incise/mesh/predicates.hpp"

namespace incise {

std::vector<TetId> inverted_at(const TetMesh& mesh, std::span<const Vec3> positions) {
  std::vector<TetId> inverted;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    if (!(signed_volume(positions[static_cast<std::size_t>(tet[0])],
                        positions[static_cast<std::size_t>(tet[1])],
                        positions[static_cast<std::size_t>(tet[2])],
                        positions[static_cast<std::size_t>(tet[3])]) > 0.0)) {
      inverted.push_back(static_cast<TetId>(t));
    }
  }
  return inverted;
}

double normalized_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double squared_sum = (b - a).squaredNorm() + (c - a).squaredNorm() + (d - a).squaredNorm() +
                             (c - b).squaredNorm() + (d - b).squaredNorm() + (d - c).squaredNorm();
  const double rms_edge = std::sqrt(squared_sum / 6.0);
  if (rms_edge == 0.0) {
    return 0.0;
  }
  // The regular tetrahedron with edge l has volume l^3 / (6 sqrt 2).
  const double regular_volume = rms_edge * rms_edge * rms_edge / (6.0 * std::sqrt(2.0));
  return signed_volume(a, b, c, d) / regular_volume;
}

namespace {

/// Tetrahedra per block of validate()'s parallel passes: each block's findings are listed in
/// tetrahedron order and the blocks joined in order, so the report is the same on any number
/// of threads.
constexpr std::size_t kValidationBlock = 4096;

/// One block's findings.
struct BlockFindings {
  std::vector<TetId> inverted;
  std::vector<TetId> degenerate;
  std::vector<TetId> slivers;
  std::vector<std::array<VertexId, 3>> nonmanifold_faces;
  std::vector<std::pair<TetId, TetId>> overlapping;
};

/// The checks of one tetrahedron: its orientation and shape, and its faces' neighbours.
void check_tet(const TetMesh& mesh, TetId id, const std::vector<char>& vertex_finite,
               const ValidationOptions& options, BlockFindings& found) {
  const auto positions = mesh.rest_positions();
  const Tet& tet = mesh.tet(id);
  if (!std::all_of(tet.begin(), tet.end(), [&](VertexId v) { return vertex_finite[v] != 0; })) {
    return;  // already reported through its vertices; predicates need finite input
  }
  const Vec3& a = positions[tet[0]];
  const Vec3& b = positions[tet[1]];
  const Vec3& c = positions[tet[2]];
  const Vec3& d = positions[tet[3]];
  const Sign orientation = orient3d(a, b, c, d);
  if (orientation == Sign::kNegative) {
    found.inverted.push_back(id);
  } else if (orientation == Sign::kZero) {
    found.degenerate.push_back(id);
  } else if (normalized_volume(a, b, c, d) < options.degenerate_tolerance) {
    found.slivers.push_back(id);
  }
  const auto& neighbors = mesh.tet_neighbors(id);
  for (int f = 0; f < 4; ++f) {
    const auto& face = tet_local::kFaces[f];
    const TetId other = neighbors[f];
    if (other == kNonManifoldFace) {
      std::array<VertexId, 3> key{tet[face[0]], tet[face[1]], tet[face[2]]};
      std::sort(key.begin(), key.end());
      found.nonmanifold_faces.push_back(key);
    } else if (other > id) {
      // Conforming neighbours lie on opposite sides of their shared face.
      const Tet& neighbor = mesh.tet(other);
      VertexId apex = kInvalidId;
      for (VertexId v : neighbor) {
        if (v != tet[face[0]] && v != tet[face[1]] && v != tet[face[2]]) {
          apex = v;
        }
      }
      if (vertex_finite[apex] != 0 &&
          orient3d(positions[tet[face[0]]], positions[tet[face[1]]], positions[tet[face[2]]],
                   positions[apex]) != Sign::kPositive &&
          orientation == Sign::kPositive) {
        found.overlapping.emplace_back(id, other);
      }
    }
  }
}

template <typename T>
void append(std::vector<T>& to, const std::vector<T>& from) {
  to.insert(to.end(), from.begin(), from.end());
}

}  // namespace

ValidationReport validate(const TetMesh& mesh, const ValidationOptions& options) {
  // The tetrahedra are checked, and their sorted vertex sets sorted, block by block on worker
  // threads (a cut checks the whole mesh after each of its hundreds of poses: at 58k
  // tetrahedra this was two thirds of `incise cut`'s time); what is found is the same, in the
  // same order, as one thread would find it.
  ValidationReport report;
  const auto positions = mesh.rest_positions();
  std::vector<char> vertex_finite(positions.size(), 1);
  for (std::size_t v = 0; v < positions.size(); ++v) {
    if (!positions[v].allFinite()) {
      vertex_finite[v] = 0;
      report.nonfinite_vertices.push_back(static_cast<VertexId>(v));
    }
    if (mesh.vertex_tets(static_cast<VertexId>(v)).empty()) {
      report.unreferenced_vertices.push_back(static_cast<VertexId>(v));
    }
  }
  const std::size_t tets = mesh.tet_count();
  const std::size_t blocks = (tets + kValidationBlock - 1) / kValidationBlock;
  std::vector<BlockFindings> found(blocks);
  // Duplicate tetrahedra: equal sorted vertex sets, found by sorting (set, id) pairs: each
  // block sorted apart, then the sorted blocks merged.
  std::vector<std::pair<Tet, TetId>> sorted(tets);
  parallel_for(0, blocks, 1, [&](std::size_t first, std::size_t last) {
    for (std::size_t block = first; block < last; ++block) {
      const std::size_t begin = block * kValidationBlock;
      const std::size_t end = std::min(tets, begin + kValidationBlock);
      for (std::size_t t = begin; t < end; ++t) {
        const auto id = static_cast<TetId>(t);
        check_tet(mesh, id, vertex_finite, options, found[block]);
        Tet key = mesh.tet(id);
        std::sort(key.begin(), key.end());
        sorted[t] = {key, id};
      }
      std::sort(sorted.begin() + static_cast<std::ptrdiff_t>(begin),
                sorted.begin() + static_cast<std::ptrdiff_t>(end));
    }
  });
  for (const BlockFindings& block : found) {
    append(report.inverted_tets, block.inverted);
    append(report.degenerate_tets, block.degenerate);
    append(report.sliver_tets, block.slivers);
    append(report.nonmanifold_faces, block.nonmanifold_faces);
    append(report.overlapping_tets, block.overlapping);
  }
  std::sort(report.nonmanifold_faces.begin(), report.nonmanifold_faces.end());
  report.nonmanifold_faces.erase(
      std::unique(report.nonmanifold_faces.begin(), report.nonmanifold_faces.end()),
      report.nonmanifold_faces.end());
  // Sorted runs of one block each, merged pairwise (the pairs are distinct: one order).
  for (std::size_t width = kValidationBlock; width < tets; width *= 2) {
    for (std::size_t begin = 0; begin + width < tets; begin += 2 * width) {
      const auto at = [&](std::size_t k) {
        return sorted.begin() + static_cast<std::ptrdiff_t>(std::min(k, tets));
      };
      std::inplace_merge(at(begin), at(begin + width), at(begin + 2 * width));
    }
  }
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i].first == sorted[i - 1].first) {
      report.duplicate_tets.emplace_back(sorted[i - 1].second, sorted[i].second);
    }
  }
  return report;
}

bool ValidationReport::ok() const {
  return usable() && sliver_tets.empty();
}

bool ValidationReport::usable() const {
  return nonfinite_vertices.empty() && inverted_tets.empty() && degenerate_tets.empty() &&
         nonmanifold_faces.empty() && overlapping_tets.empty() && duplicate_tets.empty();
}

std::size_t ValidationReport::problem_count() const {
  return nonfinite_vertices.size() + inverted_tets.size() + degenerate_tets.size() +
         sliver_tets.size() + nonmanifold_faces.size() + overlapping_tets.size() +
         duplicate_tets.size();
}

namespace {

template <typename List, typename Print>
void describe_list(std::ostringstream& out, const char* what, const List& list,
                   std::size_t max_listed, Print print) {
  if (list.empty()) {
    return;
  }
  out << list.size() << " " << what << ":";
  for (std::size_t i = 0; i < std::min(max_listed, list.size()); ++i) {
    out << " ";
    print(list[i]);
  }
  if (list.size() > max_listed) {
    out << " ...";
  }
  out << "\n";
}

}  // namespace

std::string ValidationReport::describe(std::size_t max_listed) const {
  std::ostringstream out;
  auto id = [&out](auto value) { out << value; };
  auto pair = [&out](const auto& p) { out << p.first << "/" << p.second; };
  auto face = [&out](const auto& f) { out << "(" << f[0] << "," << f[1] << "," << f[2] << ")"; };
  describe_list(out, "vertices with NaN or Inf coordinates", nonfinite_vertices, max_listed, id);
  describe_list(out, "inverted tetrahedra", inverted_tets, max_listed, id);
  describe_list(out, "degenerate tetrahedra (zero volume)", degenerate_tets, max_listed, id);
  describe_list(out, "slivers (positive but tiny volume; usable)", sliver_tets, max_listed, id);
  describe_list(out, "faces shared by more than two tetrahedra", nonmanifold_faces, max_listed,
                face);
  describe_list(out, "overlapping neighbour pairs", overlapping_tets, max_listed, pair);
  describe_list(out, "duplicate tetrahedron pairs", duplicate_tets, max_listed, pair);
  describe_list(out, "unreferenced vertices (tolerated)", unreferenced_vertices, max_listed, id);
  return out.str();
}

}  // namespace incise
