// Blade paths: the CSV contract and its errors; swept surfaces; a through-cut with physics.

#include <gtest/gtest.h>

#include <fstream>

#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/physics/mass_spring.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

std::string error_for(const std::string& csv) {
  const auto path = test::scratch_dir("blade") / "path.csv";
  std::ofstream(path) << csv;
  try {
    (void)read_blade_path(path);
  } catch (const InputError& error) {
    return error.what();
  }
  return "";
}

const char* kHeader = "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n";

TEST(BladePath, ReadsAndRoundTrips) {
  const auto path = test::scratch_dir("blade-ok") / "path.csv";
  const std::vector<BladePose> poses = {{0.0, Vec3(0, 0, 0), Vec3(0, 0, 1)},
                                        {0.5, Vec3(0.1, 0, 0), Vec3(0.1, 0, 1)}};
  write_blade_path(path, poses);
  const auto read = read_blade_path(path);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[1].tip, poses[1].tip);
  EXPECT_EQ(read[1].time, 0.5);
}

TEST(BladePath, ErrorsNameTheLine) {
  EXPECT_NE(error_for("time,a,b\n0,0,0,0,0,0,1\n").find(":1:"), std::string::npos);
  EXPECT_NE(error_for(std::string(kHeader) + "0,0,0,0,0,0,1\n0.1,0,x,0,0,0,1\n")
                .find(":3: field 3 ('x')"),
            std::string::npos);
  EXPECT_NE(error_for(std::string(kHeader) + "0,0,0,0,0,0\n").find("7 fields expected"),
            std::string::npos);
  EXPECT_NE(error_for(std::string(kHeader) + "1,0,0,0,0,0,1\n0.5,0,0,0,0,0,1\n")
                .find("time goes backwards"),
            std::string::npos);
  EXPECT_NE(error_for(std::string(kHeader) + "0,1,1,1,1,1,1\n").find("zero length"),
            std::string::npos);
  EXPECT_NE(error_for(kHeader).find("no poses"), std::string::npos);
  EXPECT_NE(error_for(std::string(kHeader) + "0,0,0,0,0,0,nan\n").find("not a finite number"),
            std::string::npos);
}

TEST(BladePath, SweptTriangles) {
  const BladePose a{0.0, Vec3(0, 0, 0), Vec3(0, 0, 1)};
  const BladePose b{0.1, Vec3(1, 0, 0), Vec3(1, 0, 1)};
  const auto triangles = swept_triangles(a, b);
  ASSERT_EQ(triangles.size(), 2u);
  double area = 0.0;
  for (const auto& t : triangles) {
    area += 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
  }
  EXPECT_NEAR(area, 1.0, 1e-15);
  EXPECT_TRUE(swept_triangles(a, a).empty());  // a blade that did not move sweeps nothing
}

TEST(ThroughCut, PiecesKeepTheirPhysics) {
  BoxGridOptions options;
  options.cells = {4, 3, 3};
  options.size = Vec3(0.04, 0.03, 0.03);
  TetMesh mesh = make_box_grid(options);
  MassSpringModel model(mesh, material_preset("liver"), {0.3, 0.0});
  BoundaryConditions conditions(mesh);
  conditions.fix(vertices_in_box(mesh, Vec3(-1, -1, -1), Vec3(1e-9, 1, 1)));  // left face only
  conditions.set_gravity(Vec3(0, 0, -9.81));
  MechanicalSystem system(mesh, model, conditions, {0.0, 20.0});
  SimulationState state(mesh);
  const double mass = model.total_mass();
  SubdivisionCutter cutter(mesh);
  std::vector<BladePose> path;
  for (int i = 0; i <= 10; ++i) {
    const double y = -0.005 + 0.04 * i / 10.0;
    path.push_back({0.01 * i, Vec3(0.0213, y, -0.01), Vec3(0.0213, y, 0.04)});
  }
  cutter.cut_along(path);
  int components = 0;
  const auto component = tet_components(mesh, &components);
  ASSERT_EQ(components, 2);
  EXPECT_TRUE(validate(mesh).ok());
  EXPECT_NEAR(cutter.stats().cut_area, 0.03 * 0.03, 1e-12);
  model.refresh();
  EXPECT_NEAR(model.total_mass(), mass, 1e-12 * mass);
  // The held piece sags a little; the free piece falls freely (z'' = -g, no spring holds it).
  BackwardEuler integrator;
  const double dt = 0.005;
  for (int s = 0; s < 20; ++s) {
    integrator.step(system, state.x.values(), state.v.values(), state.time, dt);
    state.time += dt;
  }
  double held_min_z = 1.0;
  double free_max_z = -1.0;
  const int held_component = component[static_cast<std::size_t>(mesh.vertex_tets(0)[0])];
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    for (VertexId v : mesh.tet(static_cast<TetId>(t))) {
      const double dz = state.x.values()[v].z() - mesh.rest_position(v).z();
      if (component[t] == held_component) {
        held_min_z = std::min(held_min_z, dz);
      } else {
        free_max_z = std::max(free_max_z, dz);
      }
    }
  }
  EXPECT_GT(held_min_z, -0.01);  // held: millimetres at most
  const double fall = 0.5 * 9.81 * 0.1 * 0.1;
  EXPECT_LT(free_max_z, -0.5 * fall);  // free: falling (damped by the penalty)
}

}  // namespace
}  // namespace incise
