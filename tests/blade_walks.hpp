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
#include "incise/cut/blade_walk.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
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

/// The area of the body's boundary at rest (m^2): a cut that opens adds twice its own.
inline double boundary_area(const TetMesh& mesh) {
  double area = 0.0;
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    const Vec3& a = mesh.rest_position(face.vertices[0]);
    area += 0.5 * (mesh.rest_position(face.vertices[1]) - a)
                      .cross(mesh.rest_position(face.vertices[2]) - a)
                      .norm();
  }
  return area;
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

inline std::vector<BladePose> sweep_along_x(const Box& box, double y_fraction, double end_fraction,
                                            int poses, double margin = 0.1, double dt = 0.01) {
  return incise::sweep_along_x(box.low, box.high, y_fraction, end_fraction, poses, margin, dt);
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

/// A seeded random blade walk (incise::random_blade_walk) over the box.
inline std::vector<BladePose> random_walk(const Box& box, std::mt19937& rng, int poses) {
  return random_blade_walk(box.low, box.high, rng, poses);
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
