#include "incise/engine/engine.hpp"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <limits>

#include "engine_parts.hpp"
#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mass_spring.hpp"
#include "incise/solve/integrators.hpp"

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
  TetMesh mesh = read_tet_mesh(*scene.mesh_file, ReadOptions{scene.mesh_labels}).mesh;
  if (scene.mesh_scale != 1.0) {
    std::vector<Vec3> positions(mesh.rest_positions().begin(), mesh.rest_positions().end());
    for (Vec3& position : positions) {
      position *= scene.mesh_scale;
    }
    mesh = TetMesh(std::move(positions), std::vector<Tet>(mesh.tets().begin(), mesh.tets().end()),
                   std::vector<int>(mesh.tet_labels().begin(), mesh.tet_labels().end()));
  }
  // Slivers of positive volume are simulated as they are (their mass and stiffness are small,
  // and cuts make such tetrahedra too); anything worse is refused.
  const ValidationReport report = validate(mesh);
  if (!report.usable()) {
    throw InputError(scene.mesh_file->string(), 0,
                     "the mesh is not valid for simulation:\n" + report.describe() +
                         "(`incise convert --fix-orientation` repairs inverted tetrahedra)");
  }
  return mesh;
}

/// The scene's material table (its "material" first, then one per "materials" entry) and each
/// tetrahedron's entry: the last region that holds it (by rest centroid or label), else 0.
MaterialAssignment assign_materials(const TetMesh& mesh, const SceneDescription& scene) {
  MaterialAssignment assignment{{scene.material}, {}};
  if (scene.materials.empty()) {
    return assignment;
  }
  assignment.ids.assign(mesh.tet_count(), 0);
  const std::string where = scene.file.empty() ? "<default scene>" : scene.file.string();
  for (const MaterialRegionSpec& spec : scene.materials) {
    const int id = static_cast<int>(assignment.table.size());
    assignment.table.push_back(spec.material);
    std::size_t selected = 0;
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      const auto tet = static_cast<TetId>(t);
      bool inside = false;
      if (spec.label) {
        inside = mesh.tet_label(tet) == *spec.label;
      } else {
        Vec3 centroid = Vec3::Zero();
        for (VertexId v : mesh.tet(tet)) {
          centroid += 0.25 * mesh.rest_position(v);
        }
        inside = (centroid.array() >= spec.box->first.array()).all() &&
                 (centroid.array() <= spec.box->second.array()).all();
      }
      if (inside) {
        assignment.ids[t] = id;
        ++selected;
      }
    }
    if (selected == 0) {
      throw InputError(
          where, 0,
          spec.where + " selects no tetrahedron of the mesh" +
              (spec.label ? " (no tetrahedron has region label " + std::to_string(*spec.label) +
                                "; `incise info` lists the labels)"
                          : std::string(" (by rest centroid)")));
    }
  }
  return assignment;
}

// ---- factory tables: each kind the scene names, built in one place ---------------------------

using ModelFactory = std::unique_ptr<ForceModel> (*)(TetMesh&, const SceneDescription&);
constexpr std::array<std::pair<ModelKind, ModelFactory>, 2> kModelFactories{{
    {ModelKind::kMassSpring,
     [](TetMesh& mesh, const SceneDescription& scene) -> std::unique_ptr<ForceModel> {
       return std::make_unique<MassSpringModel>(mesh, assign_materials(mesh, scene),
                                                scene.mass_spring);
     }},
    {ModelKind::kCorotationalFem,
     [](TetMesh& mesh, const SceneDescription& scene) -> std::unique_ptr<ForceModel> {
       return std::make_unique<CorotationalFemModel>(mesh, assign_materials(mesh, scene),
                                                     scene.fem);
     }},
}};

using IntegratorFactory = std::unique_ptr<Integrator> (*)(const IntegratorSpec&);
constexpr std::array<std::pair<IntegratorKind, IntegratorFactory>, 6> kIntegratorFactories{{
    {IntegratorKind::kExplicitEuler,
     [](const IntegratorSpec&) -> std::unique_ptr<Integrator> {
       return std::make_unique<ExplicitEuler>();
     }},
    {IntegratorKind::kSymplecticEuler,
     [](const IntegratorSpec&) -> std::unique_ptr<Integrator> {
       return std::make_unique<SymplecticEuler>();
     }},
    {IntegratorKind::kRungeKutta4,
     [](const IntegratorSpec&) -> std::unique_ptr<Integrator> {
       return std::make_unique<RungeKutta4>();
     }},
    {IntegratorKind::kHierarchicalRungeKutta4,
     [](const IntegratorSpec& spec) -> std::unique_ptr<Integrator> {
       return std::make_unique<HierarchicalRungeKutta4>(spec.hierarchical);
     }},
    {IntegratorKind::kBackwardEuler,
     [](const IntegratorSpec& spec) -> std::unique_ptr<Integrator> {
       return std::make_unique<BackwardEuler>(spec.backward_euler);
     }},
    {IntegratorKind::kStatic,
     [](const IntegratorSpec& spec) -> std::unique_ptr<Integrator> {
       return std::make_unique<StaticEquilibrium>(spec.static_solve);
     }},
}};

template <typename Kind, typename Factory, std::size_t N>
Factory factory_for(const std::array<std::pair<Kind, Factory>, N>& table, Kind kind) {
  for (const auto& [candidate, factory] : table) {
    if (candidate == kind) {
      return factory;
    }
  }
  INCISE_ASSERT(false, "a scene kind has no factory");
  return nullptr;
}

}  // namespace

Engine::Parts::Parts(const SceneDescription& scene)
    : description(scene),
      mesh(build_mesh(scene)),
      model(factory_for(kModelFactories, scene.model_type)(mesh, scene)),
      conditions(mesh),
      system(mesh, *model, conditions, scene.damping, scene.inversion_guard),
      state(mesh),
      integrator(factory_for(kIntegratorFactories, scene.integrator.type)(scene.integrator)) {}

Engine::Engine(const SceneDescription& scene) : parts_(std::make_unique<Parts>(scene)) {
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
  if (const auto* vertex = std::get_if<VertexId>(&spec.focus)) {
    if (static_cast<std::size_t>(*vertex) >= p.mesh.vertex_count()) {
      throw InputError(where, 0,
                       "integrator.focus names vertex " + std::to_string(*vertex) +
                           ", but the mesh has " + std::to_string(p.mesh.vertex_count()));
    }
    p.integrator->focus_on(*vertex);
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
    p.integrator->focus_on(nearest);
  }
  if ((p.integrator->needs_vertex_forces() && p.model->vertex_forces() == nullptr) ||
      (p.integrator->needs_linearization() && p.model->linearization() == nullptr)) {
    throw InputError(
        where, 0,
        "integrator.type " + p.integrator->name() + " needs " +
            (p.integrator->needs_vertex_forces() ? "per-vertex forces" : "a linearised force") +
            ", which model.type " + p.model->name() + " does not give");
  }
  p.limit = p.integrator->stability_limit(p.system);
  if (!p.integrator->implicit() && spec.dt > p.limit) {
    // The inversion guard would push back what an unstable step throws inside out, hiding the
    // instability (a body jittering in place, not a run that says it diverged): it is off.
    const bool guarded = p.system.guard().min_volume_ratio > 0.0;
    p.system.turn_guard_off();
    p.warnings.push_back(fmt::format(
        "integrator.dt = {:.3g} s exceeds the estimated stability limit {:.3g} s of {}; expect "
        "divergence (use a smaller dt or backward-euler){}",
        spec.dt, p.limit, p.integrator->name(),
        guarded ? "; the inversion guard is off, so that the instability shows" : ""));
  }
  if (p.conditions.constrained_count() == 0 && scene.gravity.norm() > 0.0) {
    p.warnings.push_back("nothing is fixed: the body falls freely under gravity");
  }
  if (scene.tool.cutter == CutterKind::kSubdivision) {
    CutterOptions options;
    options.snap_fraction = scene.tool.snap_fraction;
    options.split = scene.tool.split;
    // The blade path is given in the body's rest frame: cutting on the simulation's current
    // positions (SubdivisionCutter's deformed configuration) does not yet carry the swept
    // surface with a wound that opens non-affinely behind the blade.
    p.cutter = std::make_unique<SubdivisionCutter>(p.mesh, options);
    // The inversion guard can only push back what a step turned inside out: the edit must not.
    p.cutter->keep_right_side_out_in(&p.state.x);
  } else if (scene.tool.cutter == CutterKind::kXfem) {
    XfemCutterOptions options;
    options.quad_length = scene.tool.quad_length;
    options.min_fraction = scene.tool.min_fraction;
    p.xfem = std::make_unique<XfemCutter>(p.mesh, options);
  }
  const auto embedded = [&](const std::filesystem::path& file, double scale) {
    SurfaceMesh surface = read_surface(file);
    for (Vec3& point : surface.points) {
      point *= scale;
    }
    auto result = std::make_unique<VisualSurface>(p.mesh, std::move(surface.points),
                                                  std::move(surface.triangles));
    if (!result->original_closed()) {
      p.warnings.push_back(file.string() +
                           ": the surface is not closed; cuts split it but add no cut faces");
    }
    return result;
  };
  if (scene.visual_file) {
    p.visual = embedded(*scene.visual_file, scene.visual_scale);
  }
  if (scene.collision_file) {
    p.collision = embedded(*scene.collision_file, scene.collision_scale);
  }
  if (!scene.tool.poses.empty()) {
    p.tool = std::make_unique<ScriptedToolPath>(scene.tool.poses);
    p.blade = p.tool->pose(0, p.state.time);
    p.blade_rest = p.blade;
  }
  p.steps_per_frame = static_cast<int>(std::lround(scene.frame_dt / spec.dt));
  const auto [low, high] = bounding_box(p.mesh);
  p.body_size = (high - low).norm();
  p.last.time = p.state.time;
  (void)p.measure(p.last);
}

Engine::~Engine() = default;

void Engine::set_tool_source(std::unique_ptr<ToolPoseSource> source) {
  Parts& p = *parts_;
  p.tool = std::move(source);
  p.blade = p.tool ? p.tool->pose(p.last.frame, p.state.time) : std::nullopt;
  p.blade_passed.clear();
  p.blade_frame = p.tool ? p.tool->frame() : PoseFrame::kRest;
  p.blade_rest =
      p.blade ? std::optional<BladePose>(p.rest_pose(*p.blade, p.blade_frame)) : std::nullopt;
  p.blade_world.reset();
}

void Engine::add_sink(FrameSink& sink) {
  parts_->sinks.push_back(&sink);
  sink.begin(*this);
}

void Engine::publish_snapshots(bool enabled) {
  parts_->publishing = enabled;
  if (enabled) {
    parts_->publish();
  }
}

std::string Engine::Parts::measure(FrameRecord& record) const {
  record.vertices = mesh.vertex_count();
  record.tets = mesh.tet_count();
  record.kinetic_energy = kinetic_energy(system.masses(), state.v.values());
  record.max_displacement = 0.0;
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    const Vec3& x = state.x.values()[i];
    if (!x.allFinite() || !state.v.values()[i].allFinite()) {
      return fmt::format("vertex {} reached a non-finite position or velocity", i);
    }
    record.max_displacement = std::max(record.max_displacement,
                                       (x - mesh.rest_position(static_cast<VertexId>(i))).norm());
  }
  if (!std::isfinite(record.kinetic_energy)) {
    return "the kinetic energy is not finite";
  }
  if (record.max_displacement > 100.0 * body_size) {
    return fmt::format("a vertex moved {:.3g} m, 100 times the body's size: the motion blew up",
                       record.max_displacement);
  }
  return {};
}

const std::shared_ptr<const SurfaceTopology>& Engine::Parts::current_surface() {
  // A move can mark faces on the cut without editing the mesh: the cutter's moves count too.
  const std::size_t moves = cutter ? cutter->stats().moves : (xfem ? xfem->stats().moves : 0);
  if (!surface || surface->mesh_revision != mesh.revision() || surface_moves != moves) {
    surface_moves = moves;
    auto topology = std::make_shared<SurfaceTopology>();
    topology->mesh_revision = mesh.revision();
    topology->version = surface ? surface->version + 1 : 1;
    for (const BoundaryFace& face : boundary_faces(mesh)) {
      topology->triangles.push_back(face.vertices);
      const bool on_cut = cutter ? cutter->cut_faces().is_cut(face.tet, face.local_face)
                                 : xfem && xfem->opened(face.vertices);
      topology->on_cut.push_back(on_cut ? 1 : 0);
    }
    topology->rest_positions.resize(mesh.vertex_count());
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      topology->rest_positions[v] = mesh.rest_position(static_cast<VertexId>(v));
    }
    surface = std::move(topology);
  }
  return surface;
}

const std::shared_ptr<const SurfaceTopology>& Engine::Parts::current_visual_surface() {
  if (visual && (!visual_topology || visual_topology->version != visual->revision())) {
    auto topology = std::make_shared<SurfaceTopology>();
    topology->mesh_revision = mesh.revision();
    topology->version = visual->revision();
    topology->triangles.assign(visual->triangles().begin(), visual->triangles().end());
    topology->on_cut.assign(visual->on_cut().begin(), visual->on_cut().end());
    topology->rest_positions.assign(visual->rest_points().begin(), visual->rest_points().end());
    visual_topology = std::move(topology);
  }
  return visual_topology;
}

void Engine::Parts::publish() {
  auto snapshot = std::make_shared<Snapshot>();
  snapshot->frame = last.frame;
  snapshot->time = state.time;
  snapshot->positions.assign(state.x.values().begin(), state.x.values().end());
  snapshot->surface = current_surface();
  snapshot->blade = world_blade();
  snapshot->cd = last.cd;
  snapshot->gc = last.gc;
  snapshot->rx = last.rx;
  snapshot->tets = mesh.tet_count();
  if (cutter) {
    for (TetId t : cutter->active_tets()) {
      ActiveTet active{mesh.tet(t), 0};
      for (int k = 0; k < 4; ++k) {
        active.on_cut |= static_cast<std::uint8_t>(cutter->on_cut(active.vertices[k]) ? 1 << k : 0);
      }
      snapshot->active.push_back(active);
    }
  }
  if (visual) {
    snapshot->visual_surface = current_visual_surface();
    snapshot->visual_positions = visual->positions(state.x.values());
  }
  channel.publish(std::move(snapshot));
}

bool Engine::step() {
  Parts& p = *parts_;
  if (p.diverged) {
    return false;
  }
  FrameRecord record;
  record.frame = p.last.frame + 1;
  const double frame_dt = p.description.frame_dt;
  const double dt = p.description.integrator.dt;

  // ---- the tool: cd and gc --------------------------------------------------------------------
  ToolMotion motion = p.tool ? p.tool->motion(record.frame, frame_dt * record.frame) : ToolMotion{};
  const PoseFrame frame = p.tool ? p.tool->frame() : PoseFrame::kRest;
  // Either cutter: a stroke starts where the blade was at the start of the step (or here, when
  // it was lifted); the blade moves to `pose` and cuts what it swept. True when it moved.
  const auto cut_with = [&](auto& cutter, const BladePose& pose) {
    if (!cutter.started() || !p.blade_rest) {
      cutter.start(p.blade_rest ? *p.blade_rest : pose);
    }
    if (!p.blade_rest) {
      return false;
    }
    const std::uint64_t revision = p.mesh.revision();
    cutter.move_to(pose);
    record.edited = record.edited || p.mesh.revision() != revision;
    record.cd += cutter.stats().cd_seconds;
    record.gc += cutter.stats().gc_seconds;
    record.cut = true;
    return true;
  };
  // The cutters cut the rest mesh: a pose given in the world is carried back first.
  bool xfem_moved = false;
  const auto advance_to = [&](const std::optional<BladePose>& given) {
    const std::optional<BladePose> pose =
        given ? std::optional<BladePose>(p.rest_pose(*given, frame)) : std::nullopt;
    if (p.cutter && pose) {
      (void)cut_with(*p.cutter, *pose);
    }
    if (p.xfem && pose) {
      xfem_moved = cut_with(*p.xfem, *pose) || xfem_moved;
    }
    p.blade_rest = pose;
  };
  // The strokes' ends the source passed through since the last frame, then where it is now.
  for (const std::optional<BladePose>& given : motion.passed) {
    advance_to(given);
  }
  advance_to(motion.pose);
  if (p.cutter && p.blade_rest) {
    // Local relaxation starts at the vertex nearest the blade tip.
    const TetId holder = p.cutter->active_point_tet();
    if (holder != kInvalidId) {
      VertexId nearest = p.mesh.tet(holder)[0];
      for (VertexId v : p.mesh.tet(holder)) {
        if ((p.cutter->position(v) - p.blade_rest->tip).norm() <
            (p.cutter->position(nearest) - p.blade_rest->tip).norm()) {
          nearest = v;
        }
      }
      p.integrator->focus_on(nearest);
    }
  }
  // The picture follows splits, and the blade inside the tetrahedra it has only partly crossed.
  if (xfem_moved && (p.visual || p.collision)) {
    const auto start = Clock::now();
    for (VisualSurface* surface : {p.visual.get(), p.collision.get()}) {
      if (surface != nullptr) {
        surface->follow(p.mesh, *p.xfem);
      }
    }
    record.gc += seconds_since(start);
  }
  p.blade = motion.pose;
  p.blade_passed = std::move(motion.passed);
  p.blade_frame = frame;
  p.blade_world.reset();

  // ---- relaxation: rx -------------------------------------------------------------------------
  for (const auto& [vertex, force] : p.pushes) {
    p.conditions.add_point_force(vertex, force);  // this step only
  }
  auto start = Clock::now();
  for (int s = 0; s < p.steps_per_frame; ++s) {
    p.integrator->step(p.system, p.state.x.values(), p.state.v.values(), p.state.time, dt);
    const IntegratorStats& stats = p.integrator->stats();
    record.solver_iterations += stats.solver_iterations_last_step;
    record.rx_parts.refresh += stats.seconds_refresh;
    record.rx_parts.forces += stats.seconds_forces;
    record.rx_parts.preconditioner += stats.seconds_preconditioner;
    record.rx_parts.start += stats.seconds_solver_start;
    record.rx_parts.products += stats.seconds_products;
    record.rx_parts.vector_updates += stats.seconds_vector_updates;
    p.state.time = frame_dt * (record.frame - 1) + dt * (s + 1);
  }
  p.state.time = frame_dt * record.frame;
  record.rx = seconds_since(start);
  for (const auto& [vertex, force] : p.pushes) {
    p.conditions.add_point_force(vertex, -force);
  }
  p.pushes.clear();
  record.time = p.state.time;
  const std::string problem = p.measure(record);
  p.last = record;
  if (!problem.empty()) {
    p.diverged = true;
    p.divergence = fmt::format(
        "the simulation diverged in frame {} (t = {:.6g} s): {}. The integrator's stability "
        "limit is {:.3g} s; try a smaller integrator.dt, more damping, or backward-euler. "
        "Frames written so far stay valid.",
        record.frame, record.time, problem, p.limit);
    return false;
  }

  // ---- output: rd -----------------------------------------------------------------------------
  start = Clock::now();
  for (FrameSink* sink : p.sinks) {
    record.written = sink->frame(*this, record) || record.written;
  }
  if (p.publishing) {
    p.publish();
  }
  record.rd = seconds_since(start);
  p.last = record;
  return true;
}

void Engine::finish() {
  for (FrameSink* sink : parts_->sinks) {
    sink->end(*this);
  }
  parts_->sinks.clear();
}

int Engine::frame() const {
  return parts_->last.frame;
}
double Engine::time() const {
  return parts_->state.time;
}
const FrameRecord& Engine::last_frame() const {
  return parts_->last;
}
bool Engine::diverged() const {
  return parts_->diverged;
}
const std::string& Engine::divergence() const {
  return parts_->divergence;
}
const SceneDescription& Engine::scene() const {
  return parts_->description;
}
const TetMesh& Engine::mesh() const {
  return parts_->mesh;
}
const SimulationState& Engine::state() const {
  return parts_->state;
}
std::span<const Vec3> Engine::positions() const {
  return parts_->state.x.values();
}
const XfemCutter* Engine::xfem_cutter() const {
  return parts_->xfem.get();
}

const VisualSurface* Engine::visual() const {
  return parts_->visual.get();
}

const VisualSurface* Engine::collision() const {
  const Parts& p = *parts_;
  return p.collision ? p.collision.get() : p.visual.get();
}

void Engine::push(std::size_t triangle, const std::array<double, 3>& barycentric,
                  const Vec3& force) {
  const VisualSurface* surface = collision();
  if (surface == nullptr) {
    throw InputError("push: the scene has no collision or visual surface");
  }
  if (triangle >= surface->triangles().size() || !force.allFinite()) {
    throw InputError("push: triangle " + std::to_string(triangle) +
                     " does not exist or the force is not finite");
  }
  for (const auto& [node, weight] : carriers(*surface, triangle, barycentric)) {
    parts_->pushes.emplace_back(node, weight * force);
  }
}

std::shared_ptr<const SurfaceTopology> Engine::visual_surface() const {
  return parts_->current_visual_surface();
}

const SubdivisionCutter* Engine::cutter() const {
  return parts_->cutter.get();
}
std::vector<Triangle> Engine::cut_surface() const {
  // The boundary the snapshots publish, built once per mesh revision for both.
  const SurfaceTopology& surface = *parts_->current_surface();
  std::vector<Triangle> triangles;
  for (std::size_t k = 0; k < surface.triangles.size(); ++k) {
    if (surface.on_cut[k] != 0) {
      triangles.push_back(surface.triangles[k]);
    }
  }
  return triangles;
}
std::shared_ptr<const SurfaceTopology> Engine::surface() const {
  return parts_->current_surface();
}
const std::optional<BladePose>& Engine::blade() const {
  return parts_->blade;
}

const std::vector<std::optional<BladePose>>& Engine::blade_passed() const {
  return parts_->blade_passed;
}
PoseFrame Engine::blade_frame() const {
  return parts_->blade_frame;
}

const std::optional<BladePose>& Engine::blade_rest() const {
  return parts_->blade_rest;
}

const std::optional<BladePose>& Engine::blade_world() const {
  return parts_->world_blade();
}

const std::optional<BladePose>& Engine::Parts::world_blade() const {
  if (!blade_world || blade_world->first != last.frame) {
    std::optional<BladePose> world = blade;
    if (blade && blade_frame == PoseFrame::kRest) {
      // Drawn where the body is now: carried by the deformation around it at rest.
      if (const auto map = blade_map(mesh, mesh.rest_positions(), state.x.values(), *blade)) {
        world = mapped(*blade, *map);
      }
    }
    blade_world.emplace(last.frame, world);
  }
  return blade_world->second;
}

BladePose Engine::Parts::rest_pose(const BladePose& pose, PoseFrame frame) {
  if (frame == PoseFrame::kRest) {
    return pose;
  }
  if (const std::optional<RestMap> map = blade_rest_map(mesh, state.x.values(), pose)) {
    rest_map = *map;
  }
  return mapped(pose, rest_map);
}

const MaterialMap* Engine::materials() const {
  return parts_->model->material_map();
}
const Integrator& Engine::integrator() const {
  return *parts_->integrator;
}
double Engine::total_mass() const {
  return parts_->model->total_mass();
}
std::uint64_t Engine::guarded_tets() const {
  return parts_->system.guarded_tets();
}
std::size_t Engine::guarded_tets_most() const {
  return parts_->system.guarded_tets_most();
}
std::uint64_t Engine::backtracked_vertices() const {
  return parts_->system.backtracked_vertices();
}
std::size_t Engine::backtracked_vertices_most() const {
  return parts_->system.backtracked_vertices_most();
}
double Engine::stability_limit() const {
  return parts_->limit;
}
const std::vector<std::string>& Engine::warnings() const {
  return parts_->warnings;
}
const SnapshotChannel& Engine::snapshots() const {
  return parts_->channel;
}

RunResult run(Engine& engine, int frames, const std::function<void(const FrameRecord&)>& on_frame) {
  RunResult result;
  for (int k = 0; k < frames; ++k) {
    if (!engine.step()) {
      result.diverged = true;
      result.divergence = engine.divergence();
      break;
    }
    result.frames.push_back(engine.last_frame());
    if (on_frame) {
      on_frame(engine.last_frame());
    }
  }
  engine.finish();
  return result;
}

}  // namespace incise
