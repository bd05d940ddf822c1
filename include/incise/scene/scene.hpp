#pragma once
// Scene files: a JSON description of what to simulate. The top-level keys are a contract
// (docs in scenes/README.md); unknown keys and wrong types are errors that name the file, the
// key and the closest valid key. Relative paths resolve against the scene file's folder.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "incise/cut/blade.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/physics/corotational_fem.hpp"
#include "incise/physics/mass_spring.hpp"
#include "incise/physics/material.hpp"
#include "incise/physics/mechanical_system.hpp"
#include "incise/solve/integrators.hpp"

namespace incise {

enum class ModelKind { kMassSpring, kCorotationalFem };
enum class IntegratorKind {
  kExplicitEuler,
  kSymplecticEuler,
  kRungeKutta4,
  kHierarchicalRungeKutta4,
  kBackwardEuler,
  kStatic
};
enum class CutterKind { kNone, kSubdivision, kXfem };

/// The names scene files use for each kind ("rk4-hierarchical", ...), in one table each so the
/// parser, error messages and reports agree.
[[nodiscard]] std::string_view name_of(ModelKind kind);
[[nodiscard]] std::string_view name_of(IntegratorKind kind);
[[nodiscard]] std::string_view name_of(CutterKind kind);
[[nodiscard]] std::string_view name_of(SplitMode mode);

/// A set of vertices: those whose rest position lies in a box, or explicit ids.
struct RegionSpec {
  std::optional<std::pair<Vec3, Vec3>> box;  ///< [low, high] (m)
  std::vector<VertexId> vertices;            ///< explicit vertex ids (with or instead of the box)
  std::string where;                         ///< "fixed[1]": for error messages
};

/// A material for the tetrahedra of a region: those whose rest centroid lies in a box (m), or
/// those with a region label from the mesh file.
struct MaterialRegionSpec {
  Material material;                         ///< Pa, kg/m^3
  std::string name;                          ///< preset name, or "custom"
  std::optional<std::pair<Vec3, Vec3>> box;  ///< [low, high] (m) for the rest centroids
  std::optional<int> label;                  ///< the mesh file's region label
  std::string where;                         ///< "materials[1]": for error messages
};

/// A prescribed displacement of a region (`displacements` key), ramped in over a time.
struct DisplacementSpec {
  RegionSpec region;                 ///< the vertices moved
  Vec3 displacement = Vec3::Zero();  ///< m
  double ramp_time = 0.0;            ///< s
};

/// A constant force on a region (`forces` key), shared by its vertices.
struct ForceSpec {
  RegionSpec region;          ///< the vertices pushed
  Vec3 force = Vec3::Zero();  ///< N, total over the region
};

/// The time integrator (`integrator` key) and each kind's options.
struct IntegratorSpec {
  IntegratorKind type = IntegratorKind::kHierarchicalRungeKutta4;  ///< `type`
  double dt = 1e-3;                                                ///< s
  HierarchicalOptions hierarchical;  ///< the seed's hierarchical RK4 schemes
  /// Focus of the hierarchical traversal: a vertex id or the vertex nearest a point (m).
  std::variant<std::monostate, VertexId, Vec3> focus;
  BackwardEulerOptions backward_euler;  ///< implicit steps: Newton, the linear solver
  StaticOptions static_solve;           ///< equilibrium solves
};

/// How the tool feels in a device's hand (`tool.haptics`; incise serve's haptic loop).
struct HapticSpec {
  double rate = 1000.0;          ///< Hz, the haptic loop
  double force_limit = 3.0;      ///< N, the largest force sent to the device
  double max_force_step = 0.05;  ///< N, the largest change between consecutive samples
  /// N/m; 0: from the touched material (a rigid punch of the region's radius on a half-space)
  double contact_stiffness = 0.0;
  double contact_stiffness_limit = 1000.0;  ///< N/m, what a desktop device renders stably
  double cutting_toughness = 150.0;         ///< J/m^2: work to open one square metre of cut
  /// m/s: below this speed the cutting resistance grows in proportion to the blade's advance
  double advance_speed = 0.01;
};

/// The scalpel: a path of poses, followed frame by frame (interpolated at frame times).
struct ToolSpec {
  std::vector<BladePose> poses;  ///< empty: no scripted path (a live tool may still cut)
  /// The blade in the tool's frame (`tool.blade`; else as long as the path's first pose).
  BladeGeometry blade;
  std::string device = "Scalpel";         ///< the OpenIGTLink device name of the tool's pose
  HapticSpec haptics;                     ///< how the tool feels in a device's hand
  CutterKind cutter = CutterKind::kNone;  ///< `cutter.type`: none, subdivision or xfem
  double snap_fraction = 0.1;  ///< crossings this close to an edge's end snap to it (of the edge)
  SplitMode split = SplitMode::kMinimal;  ///< kGeneric: the seed's 1:17 style, for comparison
  double quad_length = 0.0;    ///< m, xfem: longest swept piece tested at once (0: mean edge)
  double min_fraction = 1e-3;  ///< xfem: smallest material fraction of a virtual element
};

/// Where pictures of the scene are taken from (`camera` key); absent: fitted to the body.
struct CameraSpec {
  Vec3 eye;                   ///< m
  Vec3 target;                ///< m
  Vec3 up = Vec3::UnitZ();    ///< the picture's up direction
  double fov_degrees = 35.0;  ///< vertical field of view
};

/// A scene file parsed (parse_scene, load_scene): what Engine builds. Keys, units and defaults:
/// scenes/README.md.
struct SceneDescription {
  std::filesystem::path file;  ///< empty for the built-in default scene
  std::string source_text;     ///< the JSON it was parsed from (checkpoints carry it)
  std::string description;     ///< `description`: free text
  std::optional<std::filesystem::path> mesh_file;  ///< `mesh` as a file; else `mesh.box`
  double mesh_scale = 1.0;                         ///< metres per file unit (files carry no units)
  std::string mesh_labels;    ///< VTK cell array giving region labels (empty: the first integer)
  BoxGridOptions box;         ///< used when mesh_file is empty
  std::string material_name;  ///< preset name, or "custom"
  Material material;          ///< of every tetrahedron no entry of `materials` selects
  std::vector<MaterialRegionSpec> materials;      ///< later entries win
  ModelKind model_type = ModelKind::kMassSpring;  ///< `model.type`
  MassSpringParameters mass_spring;               ///< the mass-spring model's options
  CorotationalFemParameters fem;                  ///< the corotational FEM's options
  DampingParameters damping;                      ///< mass and stiffness damping
  /// model.inversion_guard: a tetrahedron below half this share of its rest volume after a step
  /// is pushed back to it (0: off); on (0.05) by default for both models.
  InversionGuardParameters inversion_guard;
  IntegratorSpec integrator;                    ///< `integrator`
  std::vector<RegionSpec> fixed;                ///< `fixed`: vertices held at rest
  std::vector<DisplacementSpec> displacements;  ///< `displacements`
  std::vector<ForceSpec> forces;                ///< `forces`
  Vec3 gravity = Vec3::Zero();                  ///< m/s^2
  int frames = 100;                             ///< frames to run
  double frame_dt = 0.0;                     ///< s per frame; 0 means one integrator step per frame
  ToolSpec tool;                             ///< `tool` and `cutter`
  std::filesystem::path output_dir = "out";  ///< `output.dir`
  int vtu_every = 1;                         ///< write every n-th frame (the first and last always)
  std::optional<CameraSpec> camera;          ///< `camera`; absent: fitted to the body
  /// An embedded visual surface (`visual` key; OBJ, STL, PLY, VTP), written beside the frames.
  std::optional<std::filesystem::path> visual_file;
  double visual_scale = 1.0;  ///< metres per file unit (default: the mesh's)
  /// An embedded collision surface (`collision` key): where contact forces act (the haptic
  /// contact model's surface, pushes on the body); default the visual surface.
  std::optional<std::filesystem::path> collision_file;
  double collision_scale = 1.0;  ///< metres per file unit (default: the mesh's)
};

/// The blade pose at time t (s): linear interpolation between path poses, clamped at the ends.
[[nodiscard]] BladePose pose_at(const std::vector<BladePose>& poses, double t);

/// Parses a scene from JSON text; `file` names it in errors and anchors relative paths.
[[nodiscard]] SceneDescription parse_scene(const std::string& json_text,
                                           const std::filesystem::path& file);
/// Reads and parses a scene file.
[[nodiscard]] SceneDescription load_scene(const std::filesystem::path& file);
/// The default scene (the text of scenes/default.json, built in).
[[nodiscard]] SceneDescription default_scene();
[[nodiscard]] const std::string& default_scene_text();

}  // namespace incise
