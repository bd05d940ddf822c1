#include "incise/scene/scene.hpp"

#include <algorithm>
#include <array>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <span>
#include <sstream>

#include "incise/core/error.hpp"
#include "incise/core/json_reader.hpp"

namespace incise {
namespace {

using json::Context;
using json::Json;
using json::ObjectReader;
using json::resolve;
using json::type_name;

// The scene files' names of each kind: the only place they are spelled.
constexpr std::array<std::pair<std::string_view, ModelKind>, 2> kModels{{
    {"mass-spring", ModelKind::kMassSpring},
    {"corotational-fem", ModelKind::kCorotationalFem},
}};
constexpr std::array<std::pair<std::string_view, IntegratorKind>, 6> kIntegrators{{
    {"explicit-euler", IntegratorKind::kExplicitEuler},
    {"symplectic-euler", IntegratorKind::kSymplecticEuler},
    {"rk4", IntegratorKind::kRungeKutta4},
    {"rk4-hierarchical", IntegratorKind::kHierarchicalRungeKutta4},
    {"backward-euler", IntegratorKind::kBackwardEuler},
    {"static", IntegratorKind::kStatic},
}};
constexpr std::array<std::pair<std::string_view, CutterKind>, 3> kCutters{{
    {"subdivision", CutterKind::kSubdivision},
    {"xfem", CutterKind::kXfem},
    {"none", CutterKind::kNone},
}};
constexpr std::array<std::pair<std::string_view, SplitMode>, 2> kSplits{{
    {"minimal", SplitMode::kMinimal},
    {"generic", SplitMode::kGeneric},
}};

template <typename Kind, std::size_t N>
std::string_view find_name(const std::array<std::pair<std::string_view, Kind>, N>& table,
                           Kind kind) {
  for (const auto& [name, value] : table) {
    if (value == kind) {
      return name;
    }
  }
  return "?";
}

/// A preset name, or {young_modulus, poisson_ratio, density} (Pa, -, kg/m^3) starting from
/// the liver preset; `name` becomes the preset's name or "custom".
Material parse_material(const Context& context, const Json& value, const std::string& path,
                        std::string& name) {
  Material result = material_preset("liver");
  if (value.is_string()) {
    name = value.get<std::string>();
    try {
      return material_preset(name);
    } catch (const InputError& error) {
      context.fail(path, error.what());
    }
  }
  const ObjectReader material(context, value, path, {"young_modulus", "poisson_ratio", "density"});
  name = "custom";
  result.young_modulus = material.positive("young_modulus", result.young_modulus);
  result.poisson_ratio = material.number("poisson_ratio", result.poisson_ratio);
  result.density = material.positive("density", result.density);
  try {
    result.check();
  } catch (const InputError& error) {
    context.fail(path, error.what());
  }
  return result;
}

/// [[x0,y0,z0],[x1,y1,z1]] with the first corner not above the second (m).
std::pair<Vec3, Vec3> parse_box(const Context& context, const Json& box, const std::string& path) {
  if (!box.is_array() || box.size() != 2) {
    context.fail(path, "must be [[x0,y0,z0],[x1,y1,z1]]");
  }
  const Vec3 low = ObjectReader::parse_vec3(context, box[0], path + "[0]");
  const Vec3 high = ObjectReader::parse_vec3(context, box[1], path + "[1]");
  if (!(low.array() <= high.array()).all()) {
    context.fail(path, "its first corner must not exceed the second");
  }
  return {low, high};
}

RegionSpec parse_region(const Context& context, const Json& value, const std::string& path,
                        const std::vector<std::string>& extra_keys) {
  std::vector<std::string> allowed{"box", "vertices"};
  allowed.insert(allowed.end(), extra_keys.begin(), extra_keys.end());
  const ObjectReader reader(context, value, path, allowed);
  RegionSpec region;
  region.where = path;
  if (reader.has("box") == reader.has("vertices")) {
    context.fail(path,
                 "give exactly one of \"box\": [[x0,y0,z0],[x1,y1,z1]] and \"vertices\": [ids]");
  }
  if (reader.has("box")) {
    region.box = parse_box(context, reader.at("box"), reader.child("box"));
  } else {
    const Json& ids = reader.at("vertices");
    if (!ids.is_array() || ids.empty() || !std::all_of(ids.begin(), ids.end(), [](const Json& id) {
          return id.is_number_integer() && id.get<long long>() >= 0;
        })) {
      context.fail(reader.child("vertices"),
                   "must be a non-empty list of vertex ids (integers >= 0)");
    }
    for (const Json& id : ids) {
      region.vertices.push_back(static_cast<VertexId>(id.get<long long>()));
    }
  }
  return region;
}

template <typename Parse>
void parse_list(const Context& context, const ObjectReader& top, const std::string& key,
                Parse parse) {
  if (!top.has(key)) {
    return;
  }
  const Json& list = top.at(key);
  if (!list.is_array()) {
    context.fail(key, "must be a list");
  }
  for (std::size_t i = 0; i < list.size(); ++i) {
    parse(list[i], key + "[" + std::to_string(i) + "]");
  }
}

std::vector<BladePose> parse_tool_poses(const Context& context, const Json& poses) {
  if (!poses.is_array() || poses.empty()) {
    context.fail("tool.poses",
                 "must be a non-empty list of [t, tip_x, tip_y, tip_z, base_x, base_y, base_z]");
  }
  std::vector<BladePose> result;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Json& row = poses[i];
    const std::string where = "tool.poses[" + std::to_string(i) + "]";
    if (!row.is_array() || row.size() != 7 ||
        !std::all_of(row.begin(), row.end(), [](const Json& v) { return v.is_number(); })) {
      context.fail(where, "must be 7 numbers [t, tip_x, tip_y, tip_z, base_x, base_y, base_z]");
    }
    const BladePose pose{row[0].get<double>(),
                         Vec3(row[1].get<double>(), row[2].get<double>(), row[3].get<double>()),
                         Vec3(row[4].get<double>(), row[5].get<double>(), row[6].get<double>())};
    if (!result.empty() && pose.time < result.back().time) {
      context.fail(where, "time goes backwards");
    }
    if (pose.tip == pose.base) {
      context.fail(where, "the blade has zero length");
    }
    result.push_back(pose);
  }
  return result;
}

HapticSpec parse_haptics(const Context& context, const Json& json) {
  const ObjectReader haptics(context, json, "tool.haptics",
                             {"rate", "force_limit", "max_force_step", "contact_stiffness",
                              "contact_stiffness_limit", "cutting_toughness", "advance_speed"});
  HapticSpec spec;
  spec.rate = haptics.positive("rate", spec.rate);
  if (spec.rate > 20000.0) {
    context.fail("tool.haptics.rate", "must be at most 20000 Hz");
  }
  spec.force_limit = haptics.positive("force_limit", spec.force_limit);
  spec.max_force_step = haptics.positive("max_force_step", spec.max_force_step);
  spec.contact_stiffness = haptics.non_negative("contact_stiffness", spec.contact_stiffness);
  spec.contact_stiffness_limit =
      haptics.positive("contact_stiffness_limit", spec.contact_stiffness_limit);
  spec.cutting_toughness = haptics.non_negative("cutting_toughness", spec.cutting_toughness);
  spec.advance_speed = haptics.positive("advance_speed", spec.advance_speed);
  return spec;
}

}  // namespace

SceneDescription parse_scene(const std::string& json_text, const std::filesystem::path& file) {
  const Context context(json_text, file);
  const Json root = context.parse();
  const ObjectReader top(context, root, "",
                         {"description", "mesh", "material", "materials", "model", "damping",
                          "integrator", "fixed", "displacements", "forces", "gravity", "frames",
                          "frame_dt", "output", "tool", "cutter", "camera", "visual", "collision"});
  SceneDescription scene;
  scene.file = file;
  scene.source_text = json_text;
  scene.description = top.string("description", "");

  // mesh
  if (!top.has("mesh")) {
    context.fail("mesh", "is required: {\"file\": PATH} or {\"box\": {...}}");
  }
  {
    const ObjectReader mesh(context, top.at("mesh"), "mesh", {"file", "scale", "labels", "box"});
    if (mesh.has("file") == mesh.has("box")) {
      context.fail("mesh", "give exactly one of \"file\" and \"box\"");
    }
    if (mesh.has("file")) {
      scene.mesh_file = resolve(context, mesh.string("file", ""));
      scene.mesh_scale = mesh.positive("scale", 1.0);
      scene.mesh_labels = mesh.string("labels", "");
    } else {
      for (const char* key : {"scale", "labels"}) {
        if (mesh.has(key)) {
          context.fail(std::string("mesh.") + key, "applies to a mesh file only");
        }
      }
      const ObjectReader box(context, mesh.at("box"), "mesh.box",
                             {"cells", "size", "origin", "tets_per_cell"});
      if (!box.has("cells")) {
        context.fail("mesh.box.cells", "is required: [nx, ny, nz]");
      }
      const Json& cells = box.at("cells");
      if (!cells.is_array() || cells.size() != 3 ||
          !std::all_of(cells.begin(), cells.end(), [](const Json& c) {
            return c.is_number_integer() && c.get<long long>() >= 1 && c.get<long long>() <= 1000;
          })) {
        context.fail("mesh.box.cells", "must be three integers in [1, 1000]");
      }
      scene.box.cells = {cells[0].get<int>(), cells[1].get<int>(), cells[2].get<int>()};
      scene.box.size = box.vec3("size", Vec3(0.04, 0.06, 0.04));
      scene.box.origin = box.vec3("origin", Vec3::Zero());
      if (!(scene.box.size.array() > 0.0).all()) {
        context.fail("mesh.box.size", "must be positive along every axis (m)");
      }
      scene.box.tets_per_cell = box.integer("tets_per_cell", 6, 5, 6);
    }
  }

  // material: the default of every tetrahedron; "materials" override it by region
  if (top.has("material")) {
    scene.material = parse_material(context, top.at("material"), "material", scene.material_name);
  } else {
    scene.material_name = "liver";
    scene.material = material_preset("liver");
  }
  parse_list(context, top, "materials", [&](const Json& value, const std::string& path) {
    const ObjectReader reader(context, value, path, {"material", "region"});
    MaterialRegionSpec spec;
    spec.where = path;
    if (!reader.has("material") || !reader.has("region")) {
      context.fail(path,
                   "needs \"material\" (a preset name or {young_modulus, poisson_ratio, "
                   "density}) and \"region\" ({\"box\": [[x0,y0,z0],[x1,y1,z1]]} or "
                   "{\"label\": N})");
    }
    spec.material =
        parse_material(context, reader.at("material"), reader.child("material"), spec.name);
    const ObjectReader region(context, reader.at("region"), reader.child("region"),
                              {"box", "label"});
    if (region.has("box") == region.has("label")) {
      context.fail(reader.child("region"), "give exactly one of \"box\" and \"label\"");
    }
    if (region.has("label")) {
      spec.label = region.integer("label", 0, std::numeric_limits<int>::min(),
                                  std::numeric_limits<int>::max());
    } else {
      spec.box = parse_box(context, region.at("box"), region.child("box"));
    }
    scene.materials.push_back(spec);
  });

  // model
  bool fem_tangent_given = false;
  if (top.has("model")) {
    const ObjectReader model(context, top.at("model"), "model",
                             {"type", "spring_damping_ratio", "prestrain", "volume_stiffness",
                              "inversion_guard", "rayleigh", "tangent", "assemble"});
    scene.model_type = model.choice<ModelKind>("type", ModelKind::kMassSpring, kModels, "model");
    if (model.has("inversion_guard")) {
      const Json& guard = model.at("inversion_guard");
      if (guard.is_boolean()) {
        scene.inversion_guard.min_volume_ratio =
            guard.get<bool>() ? InversionGuardParameters{}.min_volume_ratio : 0.0;
      } else if (guard.is_number() && guard.get<double>() >= 0.0 && guard.get<double>() < 1.0) {
        scene.inversion_guard.min_volume_ratio = guard.get<double>();
      } else {
        context.fail("model.inversion_guard",
                     "expected true, false or the share of its rest volume below which no "
                     "tetrahedron ends a step (a number in [0, 1))");
      }
    }
    if (scene.model_type == ModelKind::kMassSpring) {
      for (const char* key : {"rayleigh", "tangent", "assemble"}) {
        if (model.has(key)) {
          context.fail(std::string("model.") + key, "applies to corotational-fem only");
        }
      }
      scene.mass_spring.spring_damping_ratio =
          model.non_negative("spring_damping_ratio", scene.mass_spring.spring_damping_ratio);
      scene.mass_spring.prestrain = model.non_negative("prestrain", scene.mass_spring.prestrain);
      if (scene.mass_spring.prestrain >= 1.0) {
        context.fail("model.prestrain", "must be below 1");
      }
      scene.mass_spring.volume_stiffness =
          model.non_negative("volume_stiffness", scene.mass_spring.volume_stiffness);
    } else {
      for (const char* key : {"spring_damping_ratio", "prestrain", "volume_stiffness"}) {
        if (model.has(key)) {
          context.fail(std::string("model.") + key, "applies to mass-spring only");
        }
      }
      if (model.has("rayleigh")) {
        const Json& rayleigh = model.at("rayleigh");
        if (!rayleigh.is_array() || rayleigh.size() != 2 || !rayleigh[0].is_number() ||
            !rayleigh[1].is_number() || !(rayleigh[0].get<double>() >= 0.0) ||
            !(rayleigh[1].get<double>() >= 0.0)) {
          context.fail("model.rayleigh",
                       "expected [alpha, beta]: two non-negative numbers (1/s and s)");
        }
        scene.fem.rayleigh_mass = rayleigh[0].get<double>();
        scene.fem.rayleigh_stiffness = rayleigh[1].get<double>();
      }
      if (model.has("tangent")) {
        const std::string tangent = model.string("tangent", "warped");
        if (tangent == "warped") {
          scene.fem.tangent = TangentKind::kWarped;
        } else if (tangent == "projected") {
          scene.fem.tangent = TangentKind::kProjected;
        } else {
          context.fail("model.tangent",
                       "unknown tangent '" + tangent + "' (known: warped, projected)");
        }
        fem_tangent_given = true;
      }
      scene.fem.assemble = model.boolean("assemble", scene.fem.assemble);
    }
  }

  // damping
  if (top.has("damping")) {
    const ObjectReader damping(context, top.at("damping"), "damping", {"viscous", "penalty"});
    scene.damping.viscous = damping.non_negative("viscous", 0.0);
    scene.damping.penalty = damping.non_negative("penalty", 0.0);
  }

  // integrator
  if (top.has("integrator")) {
    const ObjectReader integrator(context, top.at("integrator"), "integrator",
                                  {"type", "dt", "iterations", "max_depth", "focus", "newton_steps",
                                   "solver", "max_iterations", "tolerance"});
    IntegratorSpec& spec = scene.integrator;
    spec.type = integrator.choice<IntegratorKind>("type", spec.type, kIntegrators, "integrator");
    spec.dt = integrator.positive("dt", spec.dt);
    spec.hierarchical.iterations =
        integrator.integer("iterations", spec.hierarchical.iterations, 1, 1 << 20);
    spec.hierarchical.max_depth =
        integrator.integer("max_depth", spec.hierarchical.max_depth, 0, 1 << 20);
    if (integrator.has("focus")) {
      const Json& focus = integrator.at("focus");
      if (focus.is_number_integer() && focus.get<long long>() >= 0) {
        spec.focus = static_cast<VertexId>(focus.get<long long>());
      } else {
        spec.focus = ObjectReader::parse_vec3(context, focus, "integrator.focus");
      }
    }
    spec.backward_euler.newton_steps = integrator.integer("newton_steps", 1, 1, 100);
    spec.static_solve.max_iterations =
        integrator.integer("max_iterations", spec.static_solve.max_iterations, 1, 100000);
    spec.static_solve.tolerance = integrator.positive("tolerance", spec.static_solve.tolerance);
    if (integrator.has("solver")) {
      const ObjectReader solver(context, integrator.at("solver"), "integrator.solver",
                                {"type", "preconditioner", "tolerance", "max_iterations",
                                 "warm_start", "start_history", "products"});
      LinearSolverOptions options;
      try {
        options.type = parse_linear_solver_type(
            solver.string("type", spec.type == IntegratorKind::kStatic ? "auto" : "cg"));
      } catch (const InputError& error) {
        context.fail("integrator.solver.type", error.what());
      }
      try {
        options.preconditioner =
            parse_preconditioner(solver.string("preconditioner", "block-jacobi"));
      } catch (const InputError& error) {
        context.fail("integrator.solver.preconditioner", error.what());
      }
      // These read the assembled matrix, which only the FEM builds (mass-spring multiplies
      // matrix-free): refused here rather than at the first step.
      if (scene.model_type != ModelKind::kCorotationalFem &&
          (options.preconditioner == Preconditioner::kIncompleteCholesky ||
           options.preconditioner == Preconditioner::kTwoLevel)) {
        context.fail("integrator.solver.preconditioner",
                     "'" + to_string(options.preconditioner) +
                         "' needs the corotational-fem model (it reads the assembled matrix); "
                         "mass-spring takes jacobi or block-jacobi");
      }
      options.tolerance = solver.positive("tolerance", options.tolerance);
      options.max_iterations = solver.integer("max_iterations", options.max_iterations, 1, 1000000);
      options.warm_start = solver.boolean("warm_start", options.warm_start);
      options.start_history = solver.integer("start_history", options.start_history, 0, 64);
      const std::string products = solver.string("products", "single");
      if (products != "single" && products != "double") {
        context.fail("integrator.solver.products",
                     "unknown precision '" + products + "' (known: single, double)");
      }
      options.single_precision_products = products == "single";
      spec.backward_euler.solver = options;
      spec.static_solve.solver = options;
    }
  }
  // Newton's static solve converges quadratically with the projected tangent; dynamics use
  // the cheaper warped one unless the scene says otherwise.
  if (scene.model_type == ModelKind::kCorotationalFem && !fem_tangent_given &&
      scene.integrator.type == IntegratorKind::kStatic) {
    scene.fem.tangent = TangentKind::kProjected;
  }

  // boundary conditions
  parse_list(context, top, "fixed", [&](const Json& value, const std::string& path) {
    scene.fixed.push_back(parse_region(context, value, path, {}));
  });
  parse_list(context, top, "displacements", [&](const Json& value, const std::string& path) {
    const RegionSpec region = parse_region(context, value, path, {"displacement", "ramp_time"});
    const ObjectReader reader(context, value, path,
                              {"box", "vertices", "displacement", "ramp_time"});
    if (!reader.has("displacement")) {
      context.fail(path + ".displacement", "is required: [dx, dy, dz] (m)");
    }
    scene.displacements.push_back(
        {region, reader.vec3("displacement", Vec3::Zero()), reader.non_negative("ramp_time", 0.0)});
  });
  parse_list(context, top, "forces", [&](const Json& value, const std::string& path) {
    const RegionSpec region = parse_region(context, value, path, {"force"});
    const ObjectReader reader(context, value, path, {"box", "vertices", "force"});
    if (!reader.has("force")) {
      context.fail(path + ".force", "is required: [fx, fy, fz] (N, total over the region)");
    }
    scene.forces.push_back({region, reader.vec3("force", Vec3::Zero())});
  });
  scene.gravity = top.vec3("gravity", Vec3::Zero());

  scene.frames = top.integer("frames", scene.frames, 0, 100000000);
  scene.frame_dt = top.has("frame_dt") ? top.positive("frame_dt", 0.0) : scene.integrator.dt;
  const double ratio = scene.frame_dt / scene.integrator.dt;
  if (std::abs(ratio - std::round(ratio)) > 1e-6 * ratio || std::round(ratio) < 1.0) {
    context.fail("frame_dt", "must be a whole multiple of integrator.dt");
  }

  if (top.has("tool")) {
    const ObjectReader tool(context, top.at("tool"), "tool",
                            {"blade_path", "poses", "blade", "device", "haptics"});
    if (tool.has("blade_path") && tool.has("poses")) {
      context.fail("tool",
                   "give at most one of \"blade_path\": CSV and \"poses\": [[t, tip_x, tip_y, "
                   "tip_z, base_x, base_y, base_z], ...]");
    }
    if (tool.has("blade_path")) {
      scene.tool.poses = read_blade_path(resolve(context, tool.string("blade_path", "")));
    } else if (tool.has("poses")) {
      scene.tool.poses = parse_tool_poses(context, tool.at("poses"));
    }
    if (!scene.tool.poses.empty()) {
      scene.tool.blade.length =
          (scene.tool.poses.front().base - scene.tool.poses.front().tip).norm();
    }
    if (tool.has("blade")) {
      const ObjectReader blade(context, tool.at("blade"), "tool.blade", {"length", "axis"});
      scene.tool.blade.length = blade.positive("length", scene.tool.blade.length);
      const Vec3 axis = blade.vec3("axis", Vec3::UnitZ());
      if (axis.norm() < 1e-12) {
        context.fail("tool.blade.axis", "must not be zero");
      }
      scene.tool.blade.axis = axis.normalized();
    }
    scene.tool.device = tool.string("device", scene.tool.device);
    if (scene.tool.device.empty() || scene.tool.device.size() > 20) {
      context.fail("tool.device", "must be an OpenIGTLink device name of 1 to 20 characters");
    }
    if (tool.has("haptics")) {
      scene.tool.haptics = parse_haptics(context, tool.at("haptics"));
    }
    scene.tool.cutter = CutterKind::kSubdivision;
  }
  if (top.has("cutter")) {
    const ObjectReader cutter(context, top.at("cutter"), "cutter",
                              {"type", "snap_fraction", "split", "quad_length", "min_fraction"});
    scene.tool.cutter =
        cutter.choice<CutterKind>("type", CutterKind::kSubdivision, kCutters, "cutter");
    scene.tool.snap_fraction = cutter.positive("snap_fraction", 0.1);
    if (scene.tool.snap_fraction >= 0.5) {
      context.fail("cutter.snap_fraction", "must be below 0.5");
    }
    scene.tool.split = cutter.choice<SplitMode>("split", SplitMode::kMinimal, kSplits, "split");
    const bool xfem = scene.tool.cutter == CutterKind::kXfem;
    for (const char* key : {"quad_length", "min_fraction"}) {
      if (!xfem && cutter.has(key)) {
        context.fail(std::string("cutter.") + key, "applies to the xfem cutter only");
      }
    }
    for (const char* key : {"snap_fraction", "split"}) {
      if (xfem && cutter.has(key)) {
        context.fail(std::string("cutter.") + key, "applies to the subdivision cutter only");
      }
    }
    scene.tool.quad_length = cutter.has("quad_length") ? cutter.positive("quad_length", 1.0) : 0.0;
    scene.tool.min_fraction = cutter.number("min_fraction", 1e-3);
    if (!(scene.tool.min_fraction >= 0.0 && scene.tool.min_fraction < 0.5)) {
      context.fail("cutter.min_fraction", "must lie in [0, 0.5)");
    }
    // XFEM's virtual elements are weighted integrals of one rest tetrahedron each: a model
    // that integrates over elements (the corotational FEM) takes them; springs do not.
    if (xfem && scene.model_type != ModelKind::kCorotationalFem) {
      context.fail("cutter.type",
                   "xfem needs model.type \"corotational-fem\" (virtual elements are "
                   "integrated by the finite element model), not \"" +
                       std::string(name_of(scene.model_type)) + "\"");
    }
  }
  // A cutter without a tool path is kept for a live tool (the viewer's mouse, a device).

  // Embedded surfaces live in the rest tetrahedra: XFEM keeps them, subdivision does not.
  for (const char* key : {"visual", "collision"}) {
    if (!top.has(key)) {
      continue;
    }
    const ObjectReader embedded(context, top.at(key), key, {"file", "scale"});
    if (!embedded.has("file")) {
      context.fail(std::string(key) + ".file",
                   "is required: a triangle surface (OBJ, STL, PLY, VTP)");
    }
    if (scene.tool.cutter == CutterKind::kSubdivision) {
      context.fail(key, std::string("an embedded ") + key +
                            " surface needs cutter.type \"xfem\" (or no cutter): the "
                            "subdivision cutter replaces the tetrahedra it lives in");
    }
    auto& surface_file =
        std::string_view(key) == "visual" ? scene.visual_file : scene.collision_file;
    auto& scale = std::string_view(key) == "visual" ? scene.visual_scale : scene.collision_scale;
    surface_file = resolve(context, embedded.string("file", ""));
    scale = embedded.positive("scale", scene.mesh_scale);
  }

  if (top.has("output")) {
    const ObjectReader output(context, top.at("output"), "output", {"dir", "vtu_every"});
    scene.output_dir = resolve(context, output.string("dir", "out"));
    scene.vtu_every = output.integer("vtu_every", 1, 1, 100000000);
  } else {
    scene.output_dir = resolve(context, "out");
  }

  if (top.has("camera")) {
    const ObjectReader camera(context, top.at("camera"), "camera", {"eye", "target", "up", "fov"});
    if (!camera.has("eye") || !camera.has("target")) {
      context.fail("camera", "needs \"eye\" and \"target\": [x, y, z] (m)");
    }
    CameraSpec spec;
    spec.eye = camera.vec3("eye", Vec3::Zero());
    spec.target = camera.vec3("target", Vec3::Zero());
    spec.up = camera.vec3("up", Vec3::UnitZ());
    spec.fov_degrees = camera.positive("fov", 35.0);
    if ((spec.eye - spec.target).norm() == 0.0) {
      context.fail("camera.eye", "must differ from camera.target");
    }
    if (spec.up.norm() == 0.0 || (spec.eye - spec.target).cross(spec.up).norm() == 0.0) {
      context.fail("camera.up", "must be a direction not along the line of sight");
    }
    if (spec.fov_degrees >= 170.0) {
      context.fail("camera.fov", "must be below 170 degrees");
    }
    scene.camera = spec;
  }
  return scene;
}

BladePose pose_at(const std::vector<BladePose>& poses, double t) {
  if (t <= poses.front().time) {
    return {t, poses.front().tip, poses.front().base};
  }
  for (std::size_t i = 1; i < poses.size(); ++i) {
    if (t <= poses[i].time) {
      const double span = poses[i].time - poses[i - 1].time;
      const double w = span > 0.0 ? (t - poses[i - 1].time) / span : 1.0;
      return {t, (1.0 - w) * poses[i - 1].tip + w * poses[i].tip,
              (1.0 - w) * poses[i - 1].base + w * poses[i].base};
    }
  }
  return {t, poses.back().tip, poses.back().base};
}

SceneDescription load_scene(const std::filesystem::path& file) {
  std::ifstream stream(file, std::ios::binary);
  if (!stream) {
    throw InputError(file.string(), 0, "cannot open the scene file");
  }
  std::stringstream buffer;
  buffer << stream.rdbuf();
  return parse_scene(buffer.str(), file);
}

SceneDescription default_scene() {
  return parse_scene(default_scene_text(), {});
}

std::string_view name_of(ModelKind kind) {
  return find_name(kModels, kind);
}
std::string_view name_of(IntegratorKind kind) {
  return find_name(kIntegrators, kind);
}
std::string_view name_of(CutterKind kind) {
  return find_name(kCutters, kind);
}
std::string_view name_of(SplitMode mode) {
  return find_name(kSplits, mode);
}

}  // namespace incise
