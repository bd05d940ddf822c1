#include "incise/physics/inversion_guard.hpp"

#include <algorithm>
#include <array>
#include <vector>

#include "incise/core/parallel_for.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/physics/mass_spring.hpp"

namespace incise {

namespace {

std::array<Vec3, 4> corners_at(const Tet& tet, std::span<const Vec3> x) {
  return {x[static_cast<std::size_t>(tet[0])], x[static_cast<std::size_t>(tet[1])],
          x[static_cast<std::size_t>(tet[2])], x[static_cast<std::size_t>(tet[3])]};
}

double volume_of(const std::array<Vec3, 4>& p) {
  return signed_volume(p[0], p[1], p[2], p[3]);
}

/// The volume a tetrahedron is pushed back to (m^3): the share of its rest volume. It is
/// pushed only once below half of it: the gap keeps neighbours that share corners from
/// pushing each other back and forth (without it, a tangle of 13 in the soak cycled for good).
double floor_of(const TetMesh& mesh, const Tet& tet, double ratio) {
  return ratio * signed_volume(mesh.rest_position(tet[0]), mesh.rest_position(tet[1]),
                               mesh.rest_position(tet[2]), mesh.rest_position(tet[3]));
}

/// Appends `id` to `list` unless `marks` has it, and marks it. (A byte per id, unmarked by
/// unmark() after the pass: a StampedSet's four bytes per id, allocated per call, made the long
/// cut's steps outside the solver about a sixth slower, four alternating runs.)
template <typename Id>
void append_once(Id id, std::vector<std::uint8_t>& marks, std::vector<Id>& list) {
  std::uint8_t& mark = marks[static_cast<std::size_t>(id)];
  if (mark == 0) {
    mark = 1;
    list.push_back(id);
  }
}

/// Clears the marks append_once() set for `list`.
template <typename Id>
void unmark(std::span<const Id> list, std::vector<std::uint8_t>& marks) {
  for (Id id : list) {
    marks[static_cast<std::size_t>(id)] = 0;
  }
}

/// The tetrahedra around `vertices` (each once, in id order) for which `failing` holds.
/// `marks` holds a zero per tetrahedron and is left that way: it drops the duplicates. (A
/// corner's star is ~20 tetrahedra and the corners repeat: sorting the stars instead sorted
/// ~20x as many entries as there were tetrahedra to check, most of a projection pass's time.)
template <typename Failing>
std::vector<TetId> failing_around(const TetMesh& mesh, std::span<const VertexId> vertices,
                                  std::vector<std::uint8_t>& marks, const Failing& failing) {
  std::vector<TetId> around;
  for (VertexId vertex : vertices) {
    for (TetId t : mesh.vertex_tets(vertex)) {
      append_once(t, marks, around);
    }
  }
  unmark<TetId>(around, marks);
  std::erase_if(around, [&](TetId t) { return !failing(t); });
  std::sort(around.begin(), around.end());
  return around;
}

/// The fallback when projection does not settle (a fan of tetrahedra wound the wrong way round
/// an edge: no local push unwinds it): the free corners of each tetrahedron inside out are
/// moved halfway back to where the step started, their velocities halved, until none is
/// inside out. The start was right side out, and a tetrahedron with all its corners there is
/// again, so this ends: at worst its corners reach the start after 30 halvings (then snap
/// there, standing still). Returns the vertices moved.
std::size_t back_to_the_start(const TetMesh& mesh, const std::function<bool(VertexId)>& fixed,
                              std::span<const Vec3> start, std::span<Vec3> x, std::span<Vec3> v) {
  constexpr int kHalvings = 30;
  std::vector<std::uint8_t> halvings(x.size(), 0);
  std::vector<std::uint8_t> marks(mesh.tet_count(), 0);
  std::vector<TetId> inside_out;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    if (!(volume_of(corners_at(mesh.tet(static_cast<TetId>(t)), x)) > 0.0)) {
      inside_out.push_back(static_cast<TetId>(t));
    }
  }
  std::vector<VertexId> moved;
  while (!inside_out.empty()) {
    moved.clear();
    for (TetId t : inside_out) {
      for (VertexId corner : mesh.tet(t)) {
        const auto i = static_cast<std::size_t>(corner);
        if (i < start.size() && !fixed(corner) && halvings[i] <= kHalvings) {
          moved.push_back(corner);
        }
      }
    }
    std::sort(moved.begin(), moved.end());
    moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
    if (moved.empty()) {
      break;  // only fixed corners (or new ones) left to move: counted by the caller
    }
    for (VertexId corner : moved) {
      const auto i = static_cast<std::size_t>(corner);
      if (++halvings[i] > kHalvings) {
        x[i] = start[i];
        v[i] = Vec3::Zero();
      } else {
        x[i] = start[i] + 0.5 * (x[i] - start[i]);
        v[i] *= 0.5;
      }
    }
    inside_out = failing_around(mesh, moved, marks, [&](TetId t) {
      return !(volume_of(corners_at(mesh.tet(t), x)) > 0.0);
    });
  }
  std::size_t count = 0;
  for (std::uint8_t h : halvings) {
    count += h > 0 ? 1 : 0;
  }
  return count;
}

}  // namespace

InversionGuardOutcome keep_right_side_out(const TetMesh& mesh, std::span<const double> masses,
                                          const std::function<bool(VertexId)>& fixed,
                                          const InversionGuardParameters& parameters,
                                          std::span<const Vec3> start, std::span<Vec3> x,
                                          std::span<Vec3> v) {
  InversionGuardOutcome outcome;
  const double ratio = parameters.min_volume_ratio;
  if (!(ratio > 0.0)) {
    return outcome;
  }
  // Find the tetrahedra below their floor: every tetrahedron read once, in parallel; each
  // piece of the loop writes only its own flags.
  const std::size_t tets = mesh.tet_count();
  std::vector<std::uint8_t> below(tets, 0);
  parallel_for(0, tets, 4096, [&](std::size_t first, std::size_t last) {
    for (std::size_t t = first; t < last; ++t) {
      const Tet& tet = mesh.tet(static_cast<TetId>(t));
      const double volume = volume_of(corners_at(tet, x));
      if (volume < 0.5 * floor_of(mesh, tet, ratio)) {
        below[t] = 1;
      }
    }
  });
  std::vector<TetId> pending;
  for (std::size_t t = 0; t < tets; ++t) {
    if (below[t] != 0) {
      pending.push_back(static_cast<TetId>(t));
    }
  }
  if (pending.empty()) {
    return outcome;
  }
  std::vector<std::uint8_t> counted(tets, 0);
  std::vector<std::uint8_t> marks(tets, 0);
  std::vector<std::uint8_t> seen = below;  // every tetrahedron ever pending
  // The corners a pass moved, each once (most are shared by several pending tetrahedra): the
  // tetrahedra around each are checked once.
  std::vector<VertexId> moved;
  std::vector<std::uint8_t> corner_moved(x.size(), 0);
  std::array<double, 4> weight{};
  for (int pass = 0; pass < parameters.max_passes && !pending.empty(); ++pass) {
    moved.clear();
    for (TetId t : pending) {
      const Tet& tet = mesh.tet(t);
      const std::array<Vec3, 4> p = corners_at(tet, x);
      const double target = floor_of(mesh, tet, ratio);
      const double volume = volume_of(p);
      if (!(volume < 0.5 * target)) {
        continue;  // pushed back by a neighbour's projection in this pass
      }
      const double shortfall = target - volume;                 // m^3
      const std::array<Vec3, 4> gradient = volume_gradient(p);  // m^2
      double denominator = 0.0;
      for (int k = 0; k < 4; ++k) {
        const auto vertex = static_cast<std::size_t>(tet[k]);
        weight[k] = fixed(tet[k]) || !(masses[vertex] > 0.0) ? 0.0 : 1.0 / masses[vertex];
        denominator += weight[k] * gradient[k].squaredNorm();
      }
      if (!(denominator > 0.0)) {
        continue;  // every corner fixed (or the tetrahedron flat to a point): nothing can move
      }
      if (counted[t] == 0) {
        counted[t] = 1;
        ++outcome.corrected;
      }
      // Position: one linearised step onto the floor (the volume is cubic in x, so the next
      // pass checks again).
      const double lambda = shortfall / denominator;  // kg/m
      // Velocity: the rate at which the tetrahedron still closes, dV/dt = sum g_k . v_k (m^3/s).
      double closing = 0.0;
      for (int k = 0; k < 4; ++k) {
        closing += gradient[k].dot(v[static_cast<std::size_t>(tet[k])]);
      }
      const double mu = std::min(closing, 0.0) / denominator;
      for (int k = 0; k < 4; ++k) {
        const auto vertex = static_cast<std::size_t>(tet[k]);
        x[vertex] += lambda * weight[k] * gradient[k];
        v[vertex] -= mu * weight[k] * gradient[k];
      }
      // Its neighbours may have been pushed below theirs.
      for (VertexId corner : tet) {
        append_once(corner, corner_moved, moved);
      }
    }
    unmark<VertexId>(moved, corner_moved);
    pending = failing_around(mesh, moved, marks, [&](TetId t) {
      const Tet& tet = mesh.tet(t);
      return volume_of(corners_at(tet, x)) < 0.5 * floor_of(mesh, tet, ratio);
    });
    for (TetId t : pending) {
      seen[t] = 1;
    }
  }
  if (!pending.empty() && !start.empty()) {
    outcome.backtracked = back_to_the_start(mesh, fixed, start, x, v);
  }
  for (std::size_t t = 0; t < tets; ++t) {
    if (seen[t] != 0 && !(volume_of(corners_at(mesh.tet(static_cast<TetId>(t)), x)) > 0.0)) {
      ++outcome.left_inverted;
    }
  }
  return outcome;
}

}  // namespace incise
