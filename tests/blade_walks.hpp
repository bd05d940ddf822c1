#pragma once
// Blade paths and meshes shared by every cutter's tests: the tetrahedral meshes in
// ../shared/data, a straight sweep across a body, a seeded random blade walk (reversals,
// tremor, stops, re-entry, curves, tilt), a randomly perturbed grid, and playing a path.

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "incise/cut/blade.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "test_support.hpp"

namespace incise::test {

struct Box {
  Vec3 low;
  Vec3 high;
};

inline Box bounds(const TetMesh& mesh) {
  Box box{mesh.rest_position(0), mesh.rest_position(0)};
  for (const Vec3& p : mesh.rest_positions()) {
    box.low = box.low.cwiseMin(p);
    box.high = box.high.cwiseMax(p);
  }
  return box;
}

/// Every tetrahedral mesh in ../shared/data.
inline const std::vector<std::string>& data_meshes() {
  static const std::vector<std::string> all = {"sofa/liver.msh",
                                               "sofa/cylinder.msh",
                                               "sofa/cube_low_res.msh",
                                               "sofa-mor/liverTinyMesh.vtu",
                                               "sofa-mor/liverVeryCOARSE.vtu",
                                               "sofa-mor/liverCoarse.vtu",
                                               "sofa-mor/liverSemiFine.vtu",
                                               "pbd/armadillo_4k.ele",
                                               "libigl/octopus-low.mesh"};
  return all;
}

/// A vertical blade (from `margin` of the z-extent below the body to as far above it) swept
/// along x at `y_fraction` of the y-extent, from `margin` of the x-extent before the body to
/// `end_fraction` of its x-extent, in `poses` moves `dt` s apart.
inline std::vector<BladePose> sweep_along_x(const Box& box, double y_fraction, double end_fraction,
                                            int poses, double margin = 0.1, double dt = 0.01) {
  const Vec3 size = box.high - box.low;
  const double y = box.low.y() + y_fraction * size.y();
  std::vector<BladePose> path;
  for (int i = 0; i <= poses; ++i) {
    const double x =
        box.low.x() - margin * size.x() + (end_fraction + margin) * size.x() * i / poses;
    path.push_back({dt * i, Vec3(x, y, box.low.z() - margin * size.z()),
                    Vec3(x, y, box.high.z() + margin * size.z())});
  }
  return path;
}

/// Starts `cutter` at the path's first pose and moves it through the others, calling
/// after_pose(i) after move i (1-based).
template <typename Cutter, typename AfterPose>
void play(Cutter& cutter, const std::vector<BladePose>& path, AfterPose after_pose) {
  cutter.start(path.front());
  for (std::size_t i = 1; i < path.size(); ++i) {
    cutter.move_to(path[i]);
    after_pose(i);
  }
}

/// A seeded random blade walk in normalised coordinates of the box: reversals, tremor, stops,
/// leaving and re-entering the body, curves; the blade tilts as it goes.
inline std::vector<BladePose> random_walk(const Box& box, std::mt19937& rng, int poses) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> tremor(0.0, 0.004);
  const Vec3 size = box.high - box.low;
  Vec3 at(unit(rng), unit(rng), 0.5);
  double heading = 6.283 * unit(rng);
  double turn = 0.0;
  double tilt = 0.3 * (unit(rng) - 0.5);
  std::vector<BladePose> path;
  for (int i = 0; i < poses; ++i) {
    const double event = unit(rng);
    double step = 0.03;
    if (event < 0.08) {
      heading += 3.14159;  // reversal: saw back
    } else if (event < 0.14) {
      step = 0.0;  // stop
    } else if (event < 0.18) {
      at = Vec3(unit(rng), unit(rng), 0.5);  // lift out and re-enter elsewhere
    } else if (event < 0.3) {
      turn = 0.6 * (unit(rng) - 0.5);  // start a curve
    }
    heading += turn;
    at += Vec3(step * std::cos(heading) + tremor(rng), step * std::sin(heading) + tremor(rng), 0);
    at = at.cwiseMax(Vec3(-0.2, -0.2, 0.0)).cwiseMin(Vec3(1.2, 1.2, 1.0));
    tilt += tremor(rng);
    const Vec3 tip = box.low + Vec3(at.x() - tilt, at.y(), -0.1).cwiseProduct(size);
    const Vec3 base = box.low + Vec3(at.x() + tilt, at.y() + 0.5 * tilt, 1.1).cwiseProduct(size);
    path.push_back({0.01 * i, tip, base});
  }
  return path;
}

/// A 5 x 4 x 3 cm grid of 5 x 4 x 3 cells (5 or 6 tetrahedra each) whose interior vertices are
/// moved by up to a fifth of a cell: irregular, still positive.
inline TetMesh perturbed_grid(std::mt19937& rng) {
  BoxGridOptions options;
  options.cells = {5, 4, 3};
  options.size = Vec3(0.05, 0.04, 0.03);
  options.tets_per_cell = rng() % 2 == 0 ? 5 : 6;
  TetMesh grid = make_box_grid(options);
  std::uniform_real_distribution<double> shift(-0.002, 0.002);
  std::vector<Vec3> moved(grid.rest_positions().begin(), grid.rest_positions().end());
  for (Vec3& p : moved) {
    const bool interior = p.x() > 1e-9 && p.x() < 0.05 - 1e-9 && p.y() > 1e-9 &&
                          p.y() < 0.04 - 1e-9 && p.z() > 1e-9 && p.z() < 0.03 - 1e-9;
    if (interior) {
      p += Vec3(shift(rng), shift(rng), shift(rng));
    }
  }
  return TetMesh(moved, std::vector<Tet>(grid.tets().begin(), grid.tets().end()));
}

/// The body a seeded walk cuts: every third seed a real mesh (when ../shared/data is there),
/// else a perturbed grid drawn from `rng`.
inline TetMesh walk_mesh(unsigned seed, bool have_data, std::mt19937& rng) {
  if (have_data && seed % 3 == 0) {
    const std::array<const char*, 4> real = {"sofa-mor/liverVeryCOARSE.vtu", "sofa/liver.msh",
                                             "libigl/octopus-low.mesh", "sofa/cylinder.msh"};
    return read_tet_mesh(data_file(real[(seed / 3) % real.size()])).mesh;
  }
  return perturbed_grid(rng);
}

}  // namespace incise::test
