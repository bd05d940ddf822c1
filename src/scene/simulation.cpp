#include "incise/scene/simulation.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <optional>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {
namespace {

std::vector<VertexId> select(const TetMesh& mesh, const RegionSpec& region,
                             const std::string& scene) {
  std::vector<VertexId> vertices;
  if (region.box) {
    vertices = vertices_in_box(mesh, region.box->first, region.box->second);
  } else {
    for (VertexId v : region.vertices) {
      if (static_cast<std::size_t>(v) >= mesh.vertex_count()) {
        throw InputError(scene, 0,
                         region.where + " names vertex " + std::to_string(v) +
                             ", but the mesh has " + std::to_string(mesh.vertex_count()));
      }
      vertices.push_back(v);
    }
  }
  if (vertices.empty()) {
    throw InputError(scene, 0, region.where + " selects no vertex of the mesh");
  }
  return vertices;
}

TetMesh build_mesh(const SceneDescription& scene) {
  if (!scene.mesh_file) {
    return make_box_grid(scene.box);
  }
  TetMesh mesh = read_tet_mesh(*scene.mesh_file).mesh;
  if (scene.mesh_scale != 1.0) {
    std::vector<Vec3> positions(mesh.rest_positions().begin(), mesh.rest_positions().end());
    for (Vec3& position : positions) {
      position *= scene.mesh_scale;
    }
    mesh = TetMesh(std::move(positions), std::vector<Tet>(mesh.tets().begin(), mesh.tets().end()));
  }
  const ValidationReport report = validate(mesh);
  if (!report.ok()) {
    throw InputError(scene.mesh_file->string(), 0,
                     "the mesh is not valid for simulation:\n" + report.describe() +
                         "(`incise convert --fix-orientation` repairs inverted tetrahedra)");
  }
  return mesh;
}

std::unique_ptr<ForceModel> make_model(TetMesh& mesh, const SceneDescription& scene) {
  if (scene.model_type == "corotational-fem") {
    return std::make_unique<CorotationalFemModel>(mesh, scene.material, scene.fem);
  }
  return std::make_unique<MassSpringModel>(mesh, scene.material, scene.mass_spring);
}

}  // namespace

struct Simulation::Parts {
  explicit Parts(const SceneDescription& scene)
      : description(scene),
        mesh(build_mesh(scene)),
        model(make_model(mesh, scene)),
        conditions(mesh),
        system(mesh, *model, conditions, scene.damping),
        state(mesh) {}

  SceneDescription description;
  TetMesh mesh;
  std::unique_ptr<ForceModel> model;
  BoundaryConditions conditions;
  MechanicalSystem system;
  SimulationState state;
  std::unique_ptr<Integrator> integrator;
  std::unique_ptr<SubdivisionCutter> cutter;
  std::vector<std::string> warnings;
  double limit = 0.0;
};

Simulation::Simulation(const SceneDescription& scene) : parts_(std::make_unique<Parts>(scene)) {
  Parts& p = *parts_;
  const std::string where = scene.file.empty() ? "<default scene>" : scene.file.string();
  for (const RegionSpec& region : scene.fixed) {
    p.conditions.fix(select(p.mesh, region, where));
  }
  for (const DisplacementSpec& spec : scene.displacements) {
    p.conditions.prescribe_displacement(select(p.mesh, spec.region, where), spec.displacement,
                                        spec.ramp_time);
  }
  for (const ForceSpec& spec : scene.forces) {
    p.conditions.add_force(select(p.mesh, spec.region, where), spec.force);
  }
  p.conditions.set_gravity(scene.gravity);
  apply_constraints(p.system, 0.0, p.state.x.values(), p.state.v.values());

  const IntegratorSpec& spec = scene.integrator;
  if (spec.type == "explicit-euler") {
    p.integrator = std::make_unique<ExplicitEuler>();
  } else if (spec.type == "symplectic-euler") {
    p.integrator = std::make_unique<SymplecticEuler>();
  } else if (spec.type == "rk4") {
    p.integrator = std::make_unique<RungeKutta4>();
  } else if (spec.type == "backward-euler") {
    p.integrator = std::make_unique<BackwardEuler>(spec.backward_euler);
  } else if (spec.type == "static") {
    p.integrator = std::make_unique<StaticEquilibrium>(spec.static_solve);
  } else {
    auto hierarchical = std::make_unique<HierarchicalRungeKutta4>(spec.hierarchical);
    if (const auto* vertex = std::get_if<VertexId>(&spec.focus)) {
      if (static_cast<std::size_t>(*vertex) >= p.mesh.vertex_count()) {
        throw InputError(where, 0,
                         "integrator.focus names vertex " + std::to_string(*vertex) +
                             ", but the mesh has " + std::to_string(p.mesh.vertex_count()));
      }
      hierarchical->set_focus(*vertex);
    } else if (const auto* point = std::get_if<Vec3>(&spec.focus)) {
      VertexId nearest = 0;
      double best = std::numeric_limits<double>::infinity();
      for (std::size_t v = 0; v < p.mesh.vertex_count(); ++v) {
        const double distance =
            (p.mesh.rest_position(static_cast<VertexId>(v)) - *point).squaredNorm();
        if (distance < best) {
          best = distance;
          nearest = static_cast<VertexId>(v);
        }
      }
      hierarchical->set_focus(nearest);
    }
    p.integrator = std::move(hierarchical);
  }
  p.limit = explicit_stability_limit(p.system, spec.type);
  const bool implicit = spec.type == "backward-euler" || spec.type == "static";
  if (!implicit && spec.type != "rk4-hierarchical" && spec.dt > p.limit) {
    p.warnings.push_back(fmt::format(
        "integrator.dt = {:.3g} s exceeds the estimated stability limit {:.3g} s of {}; expect "
        "divergence (use a smaller dt or backward-euler)",
        spec.dt, p.limit, spec.type));
  }
  if (p.conditions.constrained_count() == 0 && scene.gravity.norm() > 0.0) {
    p.warnings.push_back("nothing is fixed: the body falls freely under gravity");
  }
  if (scene.tool.cutter == "subdivision") {
    CutterOptions options;
    options.snap_fraction = scene.tool.snap_fraction;
    options.split = scene.tool.split == "generic" ? SplitMode::kGeneric : SplitMode::kMinimal;
    // The blade path is given in the body's rest frame: cutting on the simulation's current
    // positions (SubdivisionCutter's deformed configuration) does not yet carry the swept
    // surface with a wound that opens non-affinely behind the blade.
    p.cutter = std::make_unique<SubdivisionCutter>(p.mesh, options);
  }
}

Simulation::~Simulation() = default;

const TetMesh& Simulation::mesh() const {
  return parts_->mesh;
}
const SimulationState& Simulation::state() const {
  return parts_->state;
}
const Integrator& Simulation::integrator() const {
  return *parts_->integrator;
}
double Simulation::total_mass() const {
  return parts_->model->total_mass();
}
double Simulation::stability_limit() const {
  return parts_->limit;
}
const std::vector<std::string>& Simulation::warnings() const {
  return parts_->warnings;
}

RunResult Simulation::run(int frames, const std::filesystem::path& output_dir,
                          const std::string& name, int vtu_every,
                          const std::function<void(const FrameRecord&)>& on_frame) {
  Parts& p = *parts_;
  std::error_code error;
  std::filesystem::create_directories(output_dir, error);
  if (error) {
    throw InputError(output_dir.string(), 0, "cannot create the output folder: " + error.message());
  }
  RunResult result;
  result.pvd = output_dir / (name + ".pvd");
  PvdSeries series(result.pvd);
  const double dt = p.description.integrator.dt;
  const int steps = static_cast<int>(std::lround(p.description.frame_dt / dt));
  const auto [low, high] = bounding_box(p.mesh);
  const double size = (high - low).norm();

  auto measure = [&](FrameRecord& record) {
    record.vertices = p.mesh.vertex_count();
    record.tets = p.mesh.tet_count();
    record.kinetic_energy = kinetic_energy(p.system.masses(), p.state.v.values());
    record.max_displacement = 0.0;
    for (std::size_t i = 0; i < p.mesh.vertex_count(); ++i) {
      const Vec3& x = p.state.x.values()[i];
      if (!x.allFinite() || !p.state.v.values()[i].allFinite()) {
        return fmt::format("vertex {} reached a non-finite position or velocity", i);
      }
      record.max_displacement = std::max(
          record.max_displacement, (x - p.mesh.rest_position(static_cast<VertexId>(i))).norm());
    }
    if (!std::isfinite(record.kinetic_energy)) {
      return std::string("the kinetic energy is not finite");
    }
    if (record.max_displacement > 100.0 * size) {
      return fmt::format("a vertex moved {:.3g} m, 100 times the body's size: the motion blew up",
                         record.max_displacement);
    }
    return std::string();
  };
  auto write = [&](FrameRecord& record) {
    const auto start = Clock::now();
    const std::size_t n = p.mesh.vertex_count();
    std::vector<double> displacement(3 * n);
    std::vector<double> velocity(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 d = p.state.x.values()[i] - p.mesh.rest_position(static_cast<VertexId>(i));
      const Vec3& v = p.state.v.values()[i];
      for (int k = 0; k < 3; ++k) {
        displacement[3 * i + static_cast<std::size_t>(k)] = d[k];
        velocity[3 * i + static_cast<std::size_t>(k)] = v[k];
      }
    }
    VtuFields fields;
    fields.point_data.push_back({"displacement", 3, std::move(displacement)});
    fields.point_data.push_back({"velocity", 3, std::move(velocity)});
    const std::string file = fmt::format("{}_{:06d}.vtu", name, record.frame);
    write_vtu(output_dir / file, p.mesh, p.state.x.values(), fields);
    series.add(record.time, file);
    record.written = true;
    record.rd = seconds_since(start);
  };

  FrameRecord initial;
  initial.time = p.state.time;
  (void)measure(initial);
  write(initial);
  for (int frame = 1; frame <= frames; ++frame) {
    FrameRecord record;
    record.frame = frame;
    // cd and gc: no cutter acts in this scene yet; the stages are timed all the same.
    if (p.cutter) {
      // The blade moves to its pose at the end of this frame and cuts what it swept.
      const BladePose pose = pose_at(p.description.tool.poses, p.description.frame_dt * frame);
      if (!p.cutter->started()) {
        p.cutter->start(pose_at(p.description.tool.poses, p.state.time));
      }
      p.cutter->move_to(pose);
      record.cd = p.cutter->stats().cd_seconds;
      record.gc = p.cutter->stats().gc_seconds;
      // The hierarchical relaxation focuses on the vertex nearest the blade tip.
      if (auto* hierarchical = dynamic_cast<HierarchicalRungeKutta4*>(p.integrator.get())) {
        const TetId holder = p.cutter->active_point_tet();
        if (holder != kInvalidId) {
          VertexId nearest = p.mesh.tet(holder)[0];
          for (VertexId v : p.mesh.tet(holder)) {
            if ((p.cutter->position(v) - pose.tip).norm() <
                (p.cutter->position(nearest) - pose.tip).norm()) {
              nearest = v;
            }
          }
          hierarchical->set_focus(nearest);
        }
      }
    }
    auto start = Clock::now();
    for (int s = 0; s < steps; ++s) {
      p.integrator->step(p.system, p.state.x.values(), p.state.v.values(), p.state.time, dt);
      p.state.time = p.description.frame_dt * (frame - 1) + dt * (s + 1);
    }
    p.state.time = p.description.frame_dt * frame;
    record.rx = seconds_since(start);
    record.time = p.state.time;
    const std::string problem = measure(record);
    if (!problem.empty()) {
      result.diverged = true;
      result.divergence = fmt::format(
          "the simulation diverged in frame {} (t = {:.6g} s): {}. The estimated explicit "
          "stability limit is {:.3g} s; try a smaller integrator.dt, more damping, or "
          "backward-euler. Frames written so far stay valid.",
          frame, record.time, problem, p.limit);
      break;
    }
    if (frame == frames || frame % vtu_every == 0) {
      write(record);
    }
    result.frames.push_back(record);
    if (on_frame) {
      on_frame(record);
    }
  }
  return result;
}

}  // namespace incise
