// Plan files: JSON, millimetres for lengths (converted to metres here), SI for materials.

#include <array>
#include <fstream>
#include <sstream>
#include <string_view>
#include <utility>

#include "incise/core/error.hpp"
#include "incise/core/json_reader.hpp"
#include "incise/planning/plan.hpp"

namespace incise::planning {

namespace {

using json::Context;
using json::Json;
using json::ObjectReader;

Vec3 millimetres(const ObjectReader& reader, const std::string& key, const Vec3& fallback) {
  return reader.vec3(key, fallback / kMillimetre) * kMillimetre;
}

const Json& list_at(const Context& context, const ObjectReader& reader, const std::string& key) {
  const Json& value = reader.at(key);
  if (!value.is_array()) {
    context.fail(reader.child(key), "must be a list");
  }
  return value;
}

CutPlane parse_plane(const Context& context, const Json& value, const std::string& path) {
  const ObjectReader reader(context, value, path, {"point", "normal", "radius"});
  if (!reader.has("point") || !reader.has("normal")) {
    context.fail(path, "needs a 'point' and a 'normal'");
  }
  CutPlane plane;
  plane.point = millimetres(reader, "point", Vec3::Zero());
  plane.normal = reader.vec3("normal", Vec3::UnitZ());
  if (!(plane.normal.norm() > 0.0)) {
    context.fail(path + ".normal", "must not be zero");
  }
  plane.normal.normalize();
  if (reader.has("radius")) {
    plane.radius = reader.positive("radius", 1.0) * kMillimetre;
  }
  return plane;
}

LayerMaterial parse_material(const Context& context, const ObjectReader& reader,
                             TissueElasticity elasticity) {
  LayerMaterial material;
  material.young_modulus = reader.positive("young_modulus", material.young_modulus);
  material.density = reader.positive("density", material.density);
  if (reader.has("poisson_ratio")) {
    if (elasticity != TissueElasticity::kContinuum) {
      context.fail(reader.child("poisson_ratio"),
                   "belongs with \"elasticity\": \"continuum\" (a spring lattice has its own)");
    }
    material.poisson_ratio = reader.number("poisson_ratio", material.poisson_ratio);
    if (!(material.poisson_ratio > -1.0 && material.poisson_ratio < 0.5)) {
      context.fail(reader.child("poisson_ratio"), "must lie in (-1, 0.5)");
    }
  }
  return material;
}

}  // namespace

PlanDescription parse_plan(const std::string& text, const std::filesystem::path& file) {
  const Context context(text, file, "plan");
  const Json root = context.parse();
  const ObjectReader top(context, root, "",
                         {"description",
                          "image",
                          "iso",
                          "isosurface",
                          "surfaces",
                          "decimation",
                          "skin_edge_length",
                          "layers",
                          "elasticity",
                          "materials",
                          "skin_prestrain",
                          "skin_thickness",
                          "nonlinear",
                          "volume_weight",
                          "gravity",
                          "max_thickness",
                          "min_thickness",
                          "max_edge",
                          "equilibrium",
                          "osteotomies",
                          "min_segment_volume",
                          "contact_tolerance",
                          "moves",
                          "instruments",
                          "cuts",
                          "method",
                          "solver"});
  PlanDescription plan;
  plan.file = file;
  if (top.has("image") == top.has("surfaces")) {
    context.fail(top.has("image") ? "image" : "surfaces",
                 top.has("image")
                     ? "give either 'image' or 'surfaces', not both"
                     : "one of 'image' (a CT: .mhd, .mha, DICOM file or folder, with 'iso') or "
                       "'surfaces' ({\"skin\": FILE, \"bone\": FILE}, millimetres) is required");
  }
  if (top.has("image")) {
    plan.image = json::resolve(context, top.string("image", ""));
    if (!top.has("iso")) {
      context.fail("iso", "is required with 'image': {\"skin\": S, \"bone\": B} in image values");
    }
    const ObjectReader iso(context, top.at("iso"), "iso", {"skin", "bone"});
    if (!iso.has("skin") || !iso.has("bone")) {
      context.fail("iso", "needs both 'skin' and 'bone' (image values, e.g. Hounsfield units)");
    }
    plan.skin_iso = iso.number("skin", 0.0);
    plan.bone_iso = iso.number("bone", 0.0);
    if (!(plan.bone_iso > plan.skin_iso)) {
      context.fail("iso.bone", "must exceed iso.skin (bone is denser than soft tissue)");
    }
    if (top.has("isosurface")) {
      const ObjectReader surface(context, top.at("isosurface"), "isosurface",
                                 {"facet_size", "facet_distance"});
      // mm, as the image's spacing; absent: chosen from the spacing.
      if (surface.has("facet_size")) {
        plan.isosurface.facet_size = surface.positive("facet_size", 1.0);
      }
      if (surface.has("facet_distance")) {
        plan.isosurface.facet_distance = surface.positive("facet_distance", 1.0);
      }
    }
  } else {
    if (top.has("iso") || top.has("isosurface")) {
      context.fail(top.has("iso") ? "iso" : "isosurface", "belongs with 'image'");
    }
    const ObjectReader surfaces(context, top.at("surfaces"), "surfaces", {"skin", "bone"});
    if (!surfaces.has("skin") || !surfaces.has("bone")) {
      context.fail("surfaces", "needs both 'skin' and 'bone'");
    }
    plan.skin = json::resolve(context, surfaces.string("skin", ""));
    plan.bone = json::resolve(context, surfaces.string("bone", ""));
  }
  if (top.has("decimation")) {
    const ObjectReader decimation(context, top.at("decimation"), "decimation",
                                  {"max_error", "method", "facet_size"});
    if (!decimation.has("max_error")) {
      context.fail("decimation", "needs 'max_error' (mm)");
    }
    plan.decimation_max_error = decimation.positive("max_error", 1.0) * kMillimetre;
    constexpr std::array<std::pair<std::string_view, DecimationMethod>, 2> kDecimations{
        {{"mesher", DecimationMethod::kMesher}, {"envelope", DecimationMethod::kEnvelope}}};
    plan.decimation_method = decimation.choice<DecimationMethod>("method", plan.decimation_method,
                                                                 kDecimations, "method");
    if (decimation.has("facet_size")) {
      plan.decimation_facet_size = decimation.positive("facet_size", 1.0) * kMillimetre;
    }
  }
  if (top.has("min_segment_volume")) {
    plan.min_segment_volume =
        top.positive("min_segment_volume", 1.0) * kMillimetre * kMillimetre * kMillimetre;
  }
  if (top.has("contact_tolerance")) {
    plan.contact_tolerance = top.positive("contact_tolerance", 1.0) * kMillimetre;
  }
  if (top.has("skin_edge_length")) {
    plan.skin_edge_length = top.positive("skin_edge_length", 1.0) * kMillimetre;
  }
  plan.tissue.layers = top.integer("layers", plan.tissue.layers, 1, 64);
  constexpr std::array<std::pair<std::string_view, TissueElasticity>, 2> kElasticities{
      {{"continuum", TissueElasticity::kContinuum}, {"springs", TissueElasticity::kSprings}}};
  plan.tissue.elasticity = top.choice<TissueElasticity>("elasticity", plan.tissue.elasticity,
                                                        kElasticities, "elasticity");
  const bool continuum = plan.tissue.elasticity == TissueElasticity::kContinuum;
  if (top.has("skin_thickness")) {
    if (!continuum) {
      context.fail("skin_thickness",
                   "belongs with \"elasticity\": \"continuum\" (the springs' skin is their "
                   "outer layer)");
    }
    plan.tissue.skin_thickness =
        top.non_negative("skin_thickness", plan.tissue.skin_thickness / kMillimetre) * kMillimetre;
  }
  if (top.has("materials")) {
    const Json& materials = top.at("materials");
    plan.tissue.materials.clear();
    if (materials.is_array()) {
      for (std::size_t i = 0; i < materials.size(); ++i) {
        const ObjectReader reader(context, materials[i], "materials[" + std::to_string(i) + "]",
                                  {"young_modulus", "density", "poisson_ratio"});
        plan.tissue.materials.push_back(parse_material(context, reader, plan.tissue.elasticity));
      }
      if (plan.tissue.materials.size() != 1 &&
          plan.tissue.materials.size() != static_cast<std::size_t>(plan.tissue.layers)) {
        context.fail("materials", "give one material for all layers or one per layer (" +
                                      std::to_string(plan.tissue.layers) + ")");
      }
    } else {
      const ObjectReader reader(context, materials, "materials",
                                {"young_modulus", "density", "poisson_ratio"});
      plan.tissue.materials.push_back(parse_material(context, reader, plan.tissue.elasticity));
    }
  }
  plan.tissue.skin_prestrain = top.number("skin_prestrain", plan.tissue.skin_prestrain);
  if (!(plan.tissue.skin_prestrain > -0.5 && plan.tissue.skin_prestrain < 1.0)) {
    context.fail("skin_prestrain", "must lie in (-0.5, 1)");
  }
  if (continuum && plan.tissue.skin_prestrain != 0.0 && plan.tissue.skin_thickness == 0.0) {
    context.fail("skin_prestrain", "needs a skin membrane: skin_thickness must be positive");
  }
  plan.tissue.nonlinearity = top.non_negative("nonlinear", plan.tissue.nonlinearity);
  plan.tissue.volume_weight = top.non_negative("volume_weight", plan.tissue.volume_weight);
  plan.gravity = top.vec3("gravity", plan.gravity);
  plan.tissue.max_thickness =
      top.positive("max_thickness", plan.tissue.max_thickness / kMillimetre) * kMillimetre;
  plan.tissue.min_thickness =
      top.non_negative("min_thickness", plan.tissue.min_thickness / kMillimetre) * kMillimetre;
  if (!(plan.tissue.max_thickness > plan.tissue.min_thickness)) {
    context.fail("max_thickness", "must exceed min_thickness");
  }
  plan.tissue.max_edge = top.non_negative("max_edge", 0.0) * kMillimetre;
  plan.equilibrium = top.boolean("equilibrium", plan.equilibrium);
  if (top.has("osteotomies")) {
    const Json& list = list_at(context, top, "osteotomies");
    for (std::size_t i = 0; i < list.size(); ++i) {
      plan.osteotomies.push_back(
          parse_plane(context, list[i], "osteotomies[" + std::to_string(i) + "]"));
    }
  }
  if (top.has("cuts")) {
    const Json& list = list_at(context, top, "cuts");
    for (std::size_t i = 0; i < list.size(); ++i) {
      plan.cuts.push_back(parse_plane(context, list[i], "cuts[" + std::to_string(i) + "]"));
    }
  }
  if (top.has("moves")) {
    const Json& list = list_at(context, top, "moves");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string path = "moves[" + std::to_string(i) + "]";
      const ObjectReader reader(context, list[i], path, {"segment_near", "translate", "rotate"});
      if (!reader.has("segment_near")) {
        context.fail(path, "needs 'segment_near' (a point near the bone segment to move, mm)");
      }
      RigidMove move;
      move.segment_near = millimetres(reader, "segment_near", Vec3::Zero());
      move.translation = millimetres(reader, "translate", Vec3::Zero());
      if (reader.has("rotate")) {
        const ObjectReader rotate(context, reader.at("rotate"), path + ".rotate",
                                  {"axis", "angle_deg", "center"});
        move.axis = rotate.vec3("axis", Vec3::UnitZ());
        if (!(move.axis.norm() > 0.0)) {
          context.fail(path + ".rotate.axis", "must not be zero");
        }
        move.angle = rotate.number("angle_deg", 0.0) * 3.14159265358979323846 / 180.0;
        move.center = millimetres(rotate, "center", move.segment_near);
      }
      plan.moves.push_back(move);
    }
  }
  if (top.has("instruments")) {
    const Json& list = list_at(context, top, "instruments");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string path = "instruments[" + std::to_string(i) + "]";
      const ObjectReader reader(context, list[i], path, {"near", "radius", "translate"});
      if (!reader.has("near") || !reader.has("radius")) {
        context.fail(path, "needs 'near' (mm) and 'radius' (mm)");
      }
      Instrument instrument;
      instrument.near = millimetres(reader, "near", Vec3::Zero());
      instrument.radius = reader.positive("radius", 1.0) * kMillimetre;
      instrument.translation = millimetres(reader, "translate", Vec3::Zero());
      plan.instruments.push_back(instrument);
    }
  }
  constexpr std::array<std::pair<std::string_view, PredictionMethod>, 2> kMethods{
      {{"energy", PredictionMethod::kEnergy}, {"force", PredictionMethod::kForce}}};
  plan.method = top.choice<PredictionMethod>("method", plan.method, kMethods, "method");
  // Newton's method where it applies (the energy), L-BFGS for the force objective.
  plan.solver.method =
      plan.method == PredictionMethod::kEnergy ? Minimizer::kNewton : Minimizer::kLbfgs;
  if (top.has("solver")) {
    const ObjectReader solver(context, top.at("solver"), "solver",
                              {"type", "tolerance", "max_iterations", "memory"});
    try {
      plan.solver.method = parse_minimizer(solver.string("type", to_string(plan.solver.method)));
    } catch (const InputError& error) {
      context.fail("solver.type", error.what());
    }
    if (plan.solver.method == Minimizer::kNewton && plan.method == PredictionMethod::kForce) {
      context.fail("solver.type",
                   "'newton' minimises the energy: use it with method 'energy', or give the "
                   "force method 'lbfgs' or 'cg'");
    }
    plan.relative_tolerance = solver.positive("tolerance", plan.relative_tolerance);
    plan.solver.max_iterations =
        solver.integer("max_iterations", plan.solver.max_iterations, 1, 10000000);
    plan.solver.lbfgs_memory = solver.integer("memory", plan.solver.lbfgs_memory, 1, 100);
  }
  return plan;
}

PlanDescription load_plan(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw InputError(file.string() + ": cannot open the plan");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return parse_plan(text.str(), file);
}

}  // namespace incise::planning
