// incise soak: random cuts until something breaks, or for as long as asked. Each cut draws,
// from its own seed, a body (a mesh of ../shared/data or one tetrahedralised from its
// surfaces, a regular grid whose planes the blade meets exactly, or a randomly perturbed
// grid), a cutter and model (subdivision with mass-spring or corotational FEM, XFEM with
// corotational FEM) and a blade path (a random walk with reversals, tremor, stops, re-entry
// and curves, or a straight sweep through the whole body), then runs it through the engine
// frame by frame and checks after every frame: the mesh valid, the boundary closed wherever
// it was, material volume and mass conserved, no NaN, kinetic energy bounded; after a full
// sweep, the body separated. XFEM cases embed a visual and a collision surface (the body's
// boundary, finer or offset, as real visual surfaces are), which must stay closed 2-manifolds
// with no flat triangle after every frame. A failure prints its seed and leaves scene, mesh
// and path in OUT/failures/seed-S to reproduce it with incise run.

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "commands.hpp"
#include "incise/core/atomic_file.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/blade_walk.hpp"
#include "incise/engine/engine.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/meshing/tetrahedralize.hpp"
#include "incise/xfem/visual_surface.hpp"

namespace incise::app {
namespace {

struct SoakOptions {
  unsigned seed = 1;
  int cuts = 12;
  double minutes = 0.0;  ///< 0: no time limit
  int poses = 40;
  std::string out = "out/soak";
  std::string data = "../shared/data";
  std::vector<std::string> replay;  ///< failure folders to check again instead of new cuts
};

/// One cut's choices, all drawn from its seed.
struct SoakCase {
  unsigned seed = 0;
  std::string body;  ///< what the mesh is, for the log
  TetMesh mesh;
  std::string cutter;  ///< subdivision | xfem
  std::string model;   ///< mass-spring | corotational-fem
  bool full_sweep = false;
  /// FEM only: CG with the two-level preconditioner to 1e-3, as the viewer's real-time body
  /// runs (single-precision start and products), instead of the default solver.
  bool real_time_solver = false;
  std::vector<BladePose> path;
  /// XFEM only: the embedded surfaces, made from the body's boundary: 0 the boundary as it
  /// is, 1 each triangle split in four (finer than the physics), 2 that scaled 2 % out about
  /// the centre (sticking out of the body), 3 scaled 3 % in.
  int visual_kind = -1;
};

/// What the case's description and log line add for its solver.
const char* solver_note(const SoakCase& c) {
  return c.real_time_solver ? " (real-time solver)" : "";
}

/// A body a cut may start from: a data mesh as read, or one tetrahedralised from a surface.
struct Body {
  std::string name;
  TetMesh mesh;
};

/// The tetrahedral meshes of ../shared/data, and meshes made from its surfaces as a user of
/// `incise mesh` would make them (the SOFA liver's OBJ as it is, the neonatal scalp's STL
/// remeshed at 12 mm): read or made once, then copied for each cut.
std::vector<Body> data_bodies(const std::filesystem::path& data) {
  const char* names[] = {"sofa/liver.msh",
                         "sofa/cylinder.msh",
                         "sofa/cube_low_res.msh",
                         "sofa-mor/liverTinyMesh.vtu",
                         "sofa-mor/liverVeryCOARSE.vtu",
                         "sofa-mor/liverCoarse.vtu",
                         "pbd/armadillo_4k.ele",
                         "libigl/octopus-low.mesh"};
  std::vector<Body> bodies;
  for (const char* name : names) {
    if (std::filesystem::exists(data / name)) {
      bodies.push_back(
          {std::filesystem::path(name).filename().string(), read_tet_mesh(data / name).mesh});
    }
  }
  struct Surface {
    const char* file;
    double edge_length;  // surface units; 0: as it is
  };
  for (const Surface& surface :
       {Surface{"sofa/liver.obj", 0.0}, Surface{"eit-mesher/NNscalp.stl", 12.0}}) {
    if (!std::filesystem::exists(data / surface.file)) {
      continue;
    }
    TetrahedralizeOptions options;
    if (surface.edge_length > 0.0) {
      options.remesh = TetrahedralizeOptions::Remesh::kAlways;
      options.remesh_edge_length = surface.edge_length;
    }
    bodies.push_back({std::filesystem::path(surface.file).filename().string() + " (meshed)",
                      tetrahedralize(read_surface(data / surface.file), options).mesh});
  }
  return bodies;
}

SoakCase draw_case(unsigned seed, const std::vector<Body>& bodies, int poses) {
  std::mt19937 rng(seed);
  SoakCase c;
  c.seed = seed;
  const auto kind = rng() % 3;
  BoxGridOptions grid;
  grid.cells = {3 + static_cast<int>(rng() % 4), 3 + static_cast<int>(rng() % 3),
                2 + static_cast<int>(rng() % 3)};
  grid.size = Vec3(0.01 * grid.cells[0], 0.01 * grid.cells[1], 0.01 * grid.cells[2]);
  grid.tets_per_cell = rng() % 2 == 0 ? 5 : 6;
  if (kind == 0 && !bodies.empty()) {
    const Body& body = bodies[rng() % bodies.size()];
    c.body = body.name;
    c.mesh = body.mesh;
    if (rng() % 2 == 0) {
      c.mesh = perturb_interior(c.mesh, 0.15, rng);
      c.body += " (perturbed)";
    }
  } else if (kind == 1) {
    c.body = fmt::format("{}x{}x{} grid, {} tets per cell", grid.cells[0], grid.cells[1],
                         grid.cells[2], grid.tets_per_cell);
    c.mesh = make_box_grid(grid);
  } else {
    c.body = fmt::format("perturbed {}x{}x{} grid", grid.cells[0], grid.cells[1], grid.cells[2]);
    c.mesh = perturb_interior(make_box_grid(grid), 0.2, rng);
  }
  switch (rng() % 3) {
    case 0:
      c.cutter = "subdivision";
      c.model = "mass-spring";
      break;
    case 1:
      c.cutter = "subdivision";
      c.model = "corotational-fem";
      break;
    default:
      c.cutter = "xfem";
      c.model = "corotational-fem";
  }
  // From the seed, not the generator: earlier seeds draw the same bodies and paths.
  c.real_time_solver = c.model == "corotational-fem" && c.seed % 2 == 1;
  if (c.cutter == "xfem") {
    c.visual_kind = static_cast<int>((c.seed / 2) % 4);
  }
  const auto [low, high] = bounding_box(c.mesh);
  c.full_sweep = rng() % 3 == 0;
  if (c.full_sweep) {
    // On a regular grid, half the sweeps run exactly in a plane of grid vertices.
    std::uniform_real_distribution<double> fraction(0.3, 0.7);
    double y_fraction = fraction(rng);
    if (kind == 1 && rng() % 2 == 0) {
      y_fraction = static_cast<double>(grid.cells[1] / 2) / grid.cells[1];
    }
    c.path = sweep_along_x(low, high, y_fraction, 1.1, poses);
  } else {
    c.path = random_blade_walk(low, high, rng, poses + 1);
  }
  return c;
}

const char* visual_kind_name(int kind) {
  return std::array{"on the boundary", "finer", "sticking out", "inside"}.at(
      static_cast<std::size_t>(kind));
}

/// The body's boundary as a visual surface of the given kind (SoakCase::visual_kind).
void write_visual_surface(const TetMesh& mesh, int kind, const std::filesystem::path& path) {
  std::vector<Vec3> points(mesh.rest_positions().begin(), mesh.rest_positions().end());
  std::vector<Triangle> triangles;
  for (const BoundaryFace& face : boundary_faces(mesh)) {
    triangles.push_back(face.vertices);
  }
  if (kind >= 1) {
    // Split in four through edge midpoints (shared between neighbours).
    std::map<std::pair<VertexId, VertexId>, VertexId> midpoint;
    const auto middle = [&](VertexId a, VertexId b) {
      const auto key = std::minmax(a, b);
      const auto [slot, added] = midpoint.try_emplace(key, static_cast<VertexId>(points.size()));
      if (added) {
        points.push_back(
            0.5 * (points[static_cast<std::size_t>(a)] + points[static_cast<std::size_t>(b)]));
      }
      return slot->second;
    };
    std::vector<Triangle> finer;
    for (const Triangle& t : triangles) {
      const VertexId ab = middle(t[0], t[1]);
      const VertexId bc = middle(t[1], t[2]);
      const VertexId ca = middle(t[2], t[0]);
      finer.insert(finer.end(), {Triangle{t[0], ab, ca}, Triangle{ab, t[1], bc},
                                 Triangle{ca, bc, t[2]}, Triangle{ab, bc, ca}});
    }
    triangles = std::move(finer);
  }
  if (kind >= 2) {
    const auto [low, high] = bounding_box(mesh);
    const Vec3 centre = 0.5 * (low + high);
    const double scale = kind == 2 ? 1.02 : 0.97;
    for (Vec3& p : points) {
      p = centre + scale * (p - centre);
    }
  }
  write_obj(path, points, triangles);
}

/// Writes the case as files `incise run` takes; returns the scene's path.
std::filesystem::path write_case(const SoakCase& c, const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  write_vtu(dir / "mesh.vtu", c.mesh);
  if (c.visual_kind >= 0) {
    write_visual_surface(c.mesh, c.visual_kind, dir / "visual.obj");
    write_visual_surface(c.mesh, 0, dir / "collision.obj");
  }
  write_blade_path(dir / "path.csv", c.path);
  const auto frames = static_cast<int>(c.path.size()) - 1;
  nlohmann::json integrator = {{"type", "backward-euler"}, {"dt", 0.01}};
  if (c.real_time_solver) {
    integrator["solver"] = {{"type", "cg"}, {"preconditioner", "two-level"}, {"tolerance", 1e-3}};
  }
  const nlohmann::json scene = {
      {"description",
       fmt::format("incise soak, seed {}: {}, {} with {}{}, {}", c.seed, c.body, c.cutter, c.model,
                   solver_note(c), c.full_sweep ? "full sweep" : "random walk")},
      {"mesh", {{"file", "mesh.vtu"}}},
      {"material", "liver"},
      {"model", {{"type", c.model}}},
      {"integrator", integrator},
      {"gravity", {0, 0, -9.81}},
      {"fixed",
       {{{"box", {{-1e9, -1e9, -1e9}, {1e9, 1e9, bounding_box(c.mesh).first.z() + 1e-9}}}}}},
      {"tool", {{"blade_path", "path.csv"}}},
      {"cutter", {{"type", c.cutter}}},
      {"frames", frames},
      {"frame_dt", 0.01},
      {"output", {{"dir", "out"}, {"vtu_every", 1}}}};
  nlohmann::json written = scene;
  if (c.visual_kind >= 0) {
    written["visual"] = {{"file", "visual.obj"}};
    written["collision"] = {{"file", "collision.obj"}};
    written["description"] = written["description"].get<std::string>() +
                             fmt::format(", visual surface {}", visual_kind_name(c.visual_kind));
  }
  write_file_atomically(dir / "scene.json", written.dump(2) + "\n");
  return dir / "scene.json";
}

double material_volume(const TetMesh& mesh) {
  double volume = 0.0;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    volume += std::abs(signed_volume(mesh, tet)) * mesh.material_fraction(tet);
  }
  return volume;
}

struct CaseResult {
  int frames = 0;
  std::size_t tets_before = 0;
  std::size_t tets_after = 0;
  int pieces_before = 0;
  int pieces_after = 0;
  /// XFEM with embedded surfaces: the picture's updates, and those that kept the last good
  /// picture (corefinement refused, or a result that was not a closed 2-manifold).
  std::size_t picture_updates = 0;
  std::size_t pictures_kept = 0;
  /// Most tetrahedra inside out (signed volume zero or below) in any frame's deformed state.
  std::size_t inverted_max = 0;
  std::string violation;  ///< empty: every check held
};

/// What keeps an embedded surface from being a closed 2-manifold: every edge used exactly
/// twice, once each way, and no triangle without area. Counted here, independently of the
/// surface's own check (mesh/boundary).
std::string embedded_surface_problem(const VisualSurface& surface, std::span<const Vec3> nodes) {
  std::map<std::pair<VertexId, VertexId>, std::array<int, 2>> uses;
  for (const Triangle& t : surface.triangles()) {
    for (std::size_t k = 0; k < 3; ++k) {
      const VertexId a = t[k];
      const VertexId b = t[(k + 1) % 3];
      ++uses[std::minmax(a, b)][a < b ? 0 : 1];
    }
  }
  std::size_t bad_edges = 0;
  int largest = 0;
  for (const auto& [edge, count] : uses) {
    bad_edges += count[0] == 1 && count[1] == 1 ? 0 : 1;
    largest = std::max(largest, count[0] + count[1]);
  }
  const std::span<const Vec3> rest = surface.rest_points();
  std::size_t flat = 0;
  for (const Triangle& t : surface.triangles()) {
    const Vec3& a = rest[static_cast<std::size_t>(t[0])];
    const Vec3& b = rest[static_cast<std::size_t>(t[1])];
    const Vec3& c = rest[static_cast<std::size_t>(t[2])];
    flat += (b - a).cross(c - a).norm() > 0.0 ? 0 : 1;
  }
  for (const Vec3& p : surface.positions(nodes)) {
    if (!p.allFinite()) {
      return "a point is NaN or infinite";
    }
  }
  if (bad_edges == 0 && flat == 0) {
    return "";
  }
  return fmt::format("{} edges not used once each way (largest use {}), {} flat triangles",
                     bad_edges, largest, flat);
}

/// Runs the case frame by frame, stopping at the first violated check.
CaseResult run_case(const std::filesystem::path& scene_path, bool full_sweep) {
  CaseResult result;
  const SceneDescription scene = load_scene(scene_path);
  Engine engine(scene);
  const TetMesh& mesh = engine.mesh();
  const double volume = material_volume(mesh);
  const double mass = engine.total_mass();
  const SurfaceEdgeCheck boundary_in = check_boundary(mesh);
  const int pieces_in = pieces_by_vertices(mesh);
  const bool subdivision = engine.cutter() != nullptr;
  result.tets_before = mesh.tet_count();
  result.pieces_before = pieces_in;
  const auto finish = [&] {
    result.tets_after = mesh.tet_count();
    result.pieces_after = pieces_by_vertices(mesh);
    if (const VisualSurface* visual = engine.visual()) {
      result.picture_updates = visual->revision() - 1 + visual->failures();
      result.pictures_kept = visual->failures();
    }
  };
  const double gravity = 9.81;  // m/s^2
  for (int f = 1; f <= scene.frames; ++f) {
    const bool stepped = engine.step();
    result.frames = f;
    const auto fail = [&](const std::string& what) {
      result.violation = fmt::format("frame {}: {}", f, what);
      finish();
      return result;
    };
    if (!stepped) {
      return fail("diverged: " + engine.divergence());
    }
    const ValidationReport report = validate(mesh);
    if (!report.ok()) {
      return fail("invalid mesh: " + report.describe());
    }
    for (const Vec3& p : engine.positions()) {
      if (!p.allFinite()) {
        return fail("a position is NaN or infinite");
      }
    }
    // Elements inside out in the deformed state: refused wherever the inversion guard is on
    // (every case: it is on by default for both models).
    const std::size_t inverted = inverted_at(mesh, engine.positions()).size();
    result.inverted_max = std::max(result.inverted_max, inverted);
    if (inverted > 0 && scene.inversion_guard.min_volume_ratio > 0.0) {
      return fail(fmt::format("{} tetrahedra inside out", inverted));
    }
    const double volume_now = material_volume(mesh);
    if (std::abs(volume_now - volume) > 1e-9 * volume) {
      return fail(fmt::format("material volume {} m^3, was {}", volume_now, volume));
    }
    if (std::abs(engine.total_mass() - mass) > 1e-9 * mass) {
      return fail(fmt::format("mass {} kg, was {}", engine.total_mass(), mass));
    }
    for (const VisualSurface* surface : {engine.visual(), engine.collision()}) {
      if (surface != nullptr && surface->original_closed()) {
        if (const std::string problem = embedded_surface_problem(*surface, engine.positions());
            !problem.empty()) {
          return fail(fmt::format("{} surface: {}",
                                  surface == engine.visual() ? "visual" : "collision", problem));
        }
      }
    }
    if (subdivision) {
      const SurfaceEdgeCheck boundary = check_boundary(mesh);
      if (!cut_kept_boundary(boundary_in, boundary)) {
        return fail(fmt::format("boundary broken: {} open, {} non-manifold, {} misoriented edges",
                                boundary.open_edges, boundary.nonmanifold_edges,
                                boundary.misoriented_edges));
      }
    }
    // Nothing but gravity does work: twice what free fall since the start would give.
    const double fall = gravity * engine.time();
    const double bound = mass * fall * fall + 1e-6;  // J
    if (!(engine.last_frame().kinetic_energy <= bound)) {
      return fail(fmt::format("kinetic energy {} J beyond {} J", engine.last_frame().kinetic_energy,
                              bound));
    }
  }
  finish();
  if (full_sweep) {
    // Through the whole body: it must come apart, and in the same way by shared faces as by
    // shared vertices (no piece hanging on by an edge or a corner).
    const int pieces = result.pieces_after;
    int by_faces = 0;
    (void)tet_components(mesh, &by_faces);
    if (pieces <= pieces_in || (subdivision && by_faces != pieces)) {
      result.violation =
          fmt::format("a full sweep left {} pieces by vertices ({} by faces) of {} before", pieces,
                      by_faces, pieces_in);
    }
  }
  return result;
}

/// Checks each kept failure folder again (its scene.json, with the same checks); 0 when every
/// one now holds.
int replay(const std::vector<std::string>& folders) {
  int still = 0;
  for (const std::string& folder : folders) {
    const std::filesystem::path scene = std::filesystem::path(folder) / "scene.json";
    const SceneDescription description = load_scene(scene);
    const bool full_sweep = description.description.find("full sweep") != std::string::npos;
    CaseResult result;
    try {
      result = run_case(scene, full_sweep);
    } catch (const std::exception& error) {
      result.violation = std::string("exception: ") + error.what();
    }
    still += result.violation.empty() ? 0 : 1;
    std::cout << fmt::format("{}: {}\n", folder,
                             result.violation.empty() ? "ok" : "FAILED " + result.violation);
  }
  std::cout << fmt::format("{} of {} kept failures still fail\n", still, folders.size());
  return still == 0 ? 0 : kExitInvalid;
}

int soak(const SoakOptions& options) {
  if (!options.replay.empty()) {
    return replay(options.replay);
  }
  const auto started = std::chrono::steady_clock::now();
  const auto minutes = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count() / 60;
  };
  const std::vector<Body> bodies = data_bodies(options.data);
  const std::filesystem::path out = options.out;
  std::filesystem::create_directories(out);
  std::cout << fmt::format(
      "incise soak: seeds from {}, {} cuts{}, {} data bodies from {}\n", options.seed, options.cuts,
      options.minutes > 0 ? fmt::format(" or {} minutes", options.minutes) : std::string(),
      bodies.size(), options.data);
  int done = 0;
  long long frames = 0;
  std::size_t picture_updates = 0;
  std::size_t pictures_kept = 0;
  std::size_t inverted_max = 0;  // most tetrahedra inside out in any frame of any case
  nlohmann::json failures = nlohmann::json::array();
  for (int i = 0; i < options.cuts; ++i) {
    if (options.minutes > 0 && minutes() >= options.minutes) {
      break;
    }
    const unsigned seed = options.seed + static_cast<unsigned>(i);
    const auto case_started = std::chrono::steady_clock::now();
    const SoakCase c = draw_case(seed, bodies, options.poses);
    const auto dir = out / "failures" / fmt::format("seed-{}", seed);
    const auto work = out / "work";
    std::filesystem::remove_all(work);
    CaseResult result;
    try {
      result = run_case(write_case(c, work), c.full_sweep);
    } catch (const std::exception& error) {
      result.violation = std::string("exception: ") + error.what();
    }
    ++done;
    frames += result.frames;
    picture_updates += result.picture_updates;
    pictures_kept += result.pictures_kept;
    inverted_max = std::max(inverted_max, result.inverted_max);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - case_started).count();
    std::cout << fmt::format(
                     "[{}/{}] seed {}: {}, {} + {}{}, {} of {} poses, tets {} -> {}, pieces {} -> "
                     "{}{}{}: "
                     "{} ({:.1f} s)\n",
                     done, options.cuts, seed, c.body, c.cutter, c.model, solver_note(c),
                     c.full_sweep ? "full sweep" : "random walk", c.path.size(), result.tets_before,
                     result.tets_after, result.pieces_before, result.pieces_after,
                     c.visual_kind >= 0
                         ? fmt::format(
                               ", visual surface {}: {} of {} updates kept the last picture",
                               visual_kind_name(c.visual_kind), result.pictures_kept,
                               result.picture_updates)
                         : std::string(),
                     result.inverted_max > 0
                         ? fmt::format(", up to {} tetrahedra inside out", result.inverted_max)
                         : std::string(),
                     result.violation.empty() ? "ok" : "FAILED " + result.violation, seconds)
              << std::flush;  // a long soak is watched through a pipe
    if (!result.violation.empty()) {
      std::filesystem::remove_all(dir);
      std::filesystem::create_directories(dir.parent_path());
      std::filesystem::rename(work, dir);
      std::filesystem::remove_all(dir / "out");
      write_file_atomically(dir / "violation.txt", result.violation + "\n");
      std::cout << fmt::format("  reproduce: incise run {}\n", (dir / "scene.json").string());
      failures.push_back({{"seed", seed}, {"violation", result.violation}});
    }
  }
  std::filesystem::remove_all(out / "work");
  const nlohmann::json report = {{"first_seed", options.seed},
                                 {"cuts", done},
                                 {"frames", frames},
                                 {"violations", failures.size()},
                                 {"failures", failures},
                                 {"xfem_picture_updates", picture_updates},
                                 {"xfem_pictures_kept", pictures_kept},
                                 {"inverted_tets_max", inverted_max},
                                 {"minutes", minutes()}};
  write_file_atomically(out / "soak.json", report.dump(2) + "\n");
  std::cout << fmt::format("{} cuts, {} frames checked, {} violations ({:.1f} min); report {}\n",
                           done, frames, failures.size(), minutes(), (out / "soak.json").string());
  return failures.empty() ? 0 : kExitInvalid;
}

}  // namespace

Runner add_soak_command(CLI::App& app) {
  auto options = std::make_shared<SoakOptions>();
  CLI::App* command = app.add_subcommand(
      "soak",
      "Cut random bodies along random blade paths with every cutter and model, checking "
      "every frame; failures are kept to reproduce");
  command->add_option("--seed", options->seed, "First seed (cut i uses seed + i)");
  command->add_option("--cuts", options->cuts, "Number of cuts")->check(CLI::PositiveNumber);
  command->add_option("--minutes", options->minutes, "Stop after this long (0: no limit)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--poses", options->poses, "Blade poses per cut")
      ->check(CLI::Range(2, 100000));
  command->add_option("--out", options->out, "Folder for the report and failures");
  command->add_option("--data", options->data, "Folder of data meshes (../shared/data)");
  command
      ->add_option("--replay", options->replay,
                   "Check kept failure folders (OUT/failures/seed-S) again instead")
      ->check(CLI::ExistingDirectory);
  return [options] { return soak(*options); };
}

}  // namespace incise::app
