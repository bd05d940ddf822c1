#include "incise/mesh/generators.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"

namespace incise {

TetMesh make_box_grid(const BoxGridOptions& options) {
  // Plain variables, not a structured binding: clang 14 cannot capture those in lambdas.
  const int nx = options.cells[0];
  const int ny = options.cells[1];
  const int nz = options.cells[2];
  if (nx < 1 || ny < 1 || nz < 1) {
    throw InputError("box grid needs at least one cell along each axis, got " + std::to_string(nx) +
                     " x " + std::to_string(ny) + " x " + std::to_string(nz));
  }
  if (!(options.size.array() > 0.0).all() || !options.size.allFinite()) {
    throw InputError("box size must be positive and finite along every axis");
  }
  if (options.tets_per_cell != 5 && options.tets_per_cell != 6) {
    throw InputError("tets per cell must be 5 or 6, got " + std::to_string(options.tets_per_cell));
  }
  const long long vertex_count = 1LL * (nx + 1) * (ny + 1) * (nz + 1);
  const long long tet_count = 1LL * nx * ny * nz * options.tets_per_cell;
  if (vertex_count > 1'000'000'000LL || tet_count > 1'000'000'000LL) {
    throw InputError("box grid too large: " + std::to_string(tet_count) + " tetrahedra");
  }

  std::vector<Vec3> positions;
  positions.reserve(static_cast<std::size_t>(vertex_count));
  const Vec3 step = options.size.cwiseQuotient(Vec3(nx, ny, nz));
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        // The last layer sits exactly on the far face, free of accumulated round-off.
        positions.emplace_back(
            i == nx ? options.origin.x() + options.size.x() : options.origin.x() + i * step.x(),
            j == ny ? options.origin.y() + options.size.y() : options.origin.y() + j * step.y(),
            k == nz ? options.origin.z() + options.size.z() : options.origin.z() + k * step.z());
      }
    }
  }
  auto vertex = [&](int i, int j, int k) {
    return static_cast<VertexId>((k * (ny + 1) + j) * (nx + 1) + i);
  };

  std::vector<Tet> tets;
  tets.reserve(static_cast<std::size_t>(tet_count));
  auto emit = [&](const Tet& tet) {
    // Make every tetrahedron positive (the grid is axis-aligned, so the sign is reliable).
    Tet oriented = tet;
    if (signed_volume(positions[tet[0]], positions[tet[1]], positions[tet[2]], positions[tet[3]]) <
        0.0) {
      std::swap(oriented[2], oriented[3]);
    }
    tets.push_back(oriented);
  };

  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        // corner(b) for b = x-bit | y-bit << 1 | z-bit << 2
        auto corner = [&](int bits) {
          return vertex(i + (bits & 1), j + ((bits >> 1) & 1), k + ((bits >> 2) & 1));
        };
        if (options.tets_per_cell == 6) {
          // Kuhn split: one tet per monotone path 000 -> 111 through the axis permutations.
          static constexpr std::array<std::array<int, 3>, 6> kPermutations = {
              {{{0, 1, 2}}, {{0, 2, 1}}, {{1, 0, 2}}, {{1, 2, 0}}, {{2, 0, 1}}, {{2, 1, 0}}}};
          for (const auto& axes : kPermutations) {
            const int first = 1 << axes[0];
            const int second = first | (1 << axes[1]);
            emit({corner(0), corner(first), corner(second), corner(7)});
          }
        } else {
          // Even cells keep corners 000,110,101,011 in the central tet, odd cells the others.
          const bool even = ((i + j + k) % 2) == 0;
          const int center[4] = {even ? 0 : 1, even ? 3 : 2, even ? 5 : 4, even ? 6 : 7};
          emit({corner(center[0]), corner(center[1]), corner(center[2]), corner(center[3])});
          // Each remaining corner forms a tet with its three axis neighbours.
          for (int bits = 0; bits < 8; ++bits) {
            if (std::find(std::begin(center), std::end(center), bits) != std::end(center)) {
              continue;
            }
            emit({corner(bits), corner(bits ^ 1), corner(bits ^ 2), corner(bits ^ 4)});
          }
        }
      }
    }
  }
  return TetMesh(std::move(positions), std::move(tets));
}

TetMesh perturb_interior(const TetMesh& mesh, double fraction, std::mt19937& rng) {
  std::vector<bool> on_boundary(mesh.vertex_count(), false);
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    for (VertexId v : face.vertices) {
      on_boundary[v] = true;
    }
  }
  std::vector<Vec3> points(mesh.rest_positions().begin(), mesh.rest_positions().end());
  const std::vector<Tet> tets(mesh.tets().begin(), mesh.tets().end());
  const auto volume = [&](TetId t) {
    const Tet& v = tets[t];
    return signed_volume(points[v[0]], points[v[1]], points[v[2]], points[v[3]]);
  };
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::size_t v = 0; v < points.size(); ++v) {
    const auto vertex = static_cast<VertexId>(v);
    if (on_boundary[v] || mesh.vertex_tets(vertex).empty()) {
      continue;
    }
    double shortest = std::numeric_limits<double>::infinity();
    for (TetId t : mesh.vertex_tets(vertex)) {
      for (VertexId other : tets[t]) {
        if (other != vertex) {
          shortest = std::min(shortest, (points[other] - points[v]).norm());
        }
      }
    }
    // Drawn one after the other: the same mesh from the same seed with any compiler.
    const double dx = unit(rng);
    const double dy = unit(rng);
    const double dz = unit(rng);
    const Vec3 before = points[v];
    std::vector<double> volumes_before;
    for (TetId t : mesh.vertex_tets(vertex)) {
      volumes_before.push_back(volume(t));
    }
    points[v] += fraction * shortest * Vec3(dx, dy, dz);
    std::size_t k = 0;
    for (TetId t : mesh.vertex_tets(vertex)) {
      if (volume(t) < 0.2 * volumes_before[k++]) {
        points[v] = before;
        break;
      }
    }
  }
  return TetMesh(points, tets);
}

}  // namespace incise
