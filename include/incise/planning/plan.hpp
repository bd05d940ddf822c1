#pragma once
// A surgical plan (`incise plan PLAN.json`): the surfaces, the layered tissue's parameters,
// the osteotomies and segment moves, instruments and soft-tissue cuts, and how to predict.
// Lengths in a plan and in its outputs are millimetres (as in DICOM and the surface files);
// materials are SI (Pa, kg/m^3), gravity m/s^2, forces N. Inside, everything is SI.

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "incise/imaging/isosurface.hpp"
#include "incise/planning/layered_tissue.hpp"
#include "incise/planning/minimize.hpp"
#include "incise/planning/osteotomy.hpp"

namespace incise::planning {

/// m: a plan's files give lengths in millimetres; this converts them.
inline constexpr double kMillimetre = 1e-3;

/// Skin points near a point are held by an instrument and carried by `translation`.
struct Instrument {
  Vec3 near = Vec3::Zero();         ///< m
  double radius = 0.0;              ///< m
  Vec3 translation = Vec3::Zero();  ///< m
};

enum class PredictionMethod { kEnergy, kForce };
enum class DecimationMethod { kMesher, kEnvelope };

/// A surgical plan, as `incise plan` reads it from JSON (keys: scenes/README.md, "Plans").
/// Lengths in m here (the JSON's mm converted), angles in rad.
struct PlanDescription {
  std::filesystem::path file;  ///< the plan (outputs and messages name it)
  /// A CT volume (MetaImage, DICOM file or folder) whose isosurfaces give skin and bone, or...
  std::filesystem::path image;
  double skin_iso = 0.0;                  ///< image values (Hounsfield units for a DICOM CT)
  double bone_iso = 0.0;                  ///< the same for the bone
  imaging::IsosurfaceOptions isosurface;  ///< mm
  /// ...surface files (mm), resolved against the plan's folder.
  std::filesystem::path skin;
  std::filesystem::path bone;                  ///< the bone's surface file
  std::optional<double> decimation_max_error;  ///< m
  /// How surface files meet decimation_max_error: remeshed as a level set by the CT's mesher
  /// (seconds; the bound at each triangle's centre, the distance measured both ways), or
  /// decimated by edge collapse inside CGAL's polyhedral envelope (every point within the bound:
  /// the seed's guarantee, minutes for a 200,000-triangle surface).
  DecimationMethod decimation_method = DecimationMethod::kMesher;
  /// m: with the mesher, the largest triangle circumradius; 0: the layer thickness
  /// (max_thickness / layers), as for a CT.
  double decimation_facet_size = 0.0;
  /// m: the skin remeshed isotropically to this edge length before the model is built
  /// (well-shaped prisms; a scan's slivers make the minimisation crawl).
  std::optional<double> skin_edge_length;
  LayeredTissueOptions tissue;           ///< the soft tissue's layers and materials
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);  ///< m/s^2
  bool equilibrium = true;               ///< initialise the equilibrium first
  std::vector<CutPlane> osteotomies;     ///< the bone's cuts
  /// m^3: bone pieces enclosing less are not segments: a CT's specks are left out, and an
  /// osteotomy's fragments join the segment they share the most cut edges with.
  double min_segment_volume = 5e-7;
  /// m: moved segments may overlap this deep at their cut (the saw's kerf, surfaces meshed
  /// to within half a millimetre) before a move is refused as interpenetration.
  double contact_tolerance = 5e-4;
  std::vector<RigidMove> moves;         ///< each moves the segment nearest its point
  std::vector<Instrument> instruments;  ///< tools that push the skin
  std::vector<CutPlane> cuts;           ///< soft-tissue cuts (discs)
  PredictionMethod method = PredictionMethod::kEnergy;  ///< minimise energy or forces
  MinimizeOptions solver;                               ///< the minimiser
  /// Converged when the largest free force is below this fraction of the largest point weight.
  double relative_tolerance = 1e-4;
};

/// Parses a plan's JSON text; every key is checked and an unknown key or a bad value throws an
/// InputError naming the file, the line and the key.
[[nodiscard]] PlanDescription parse_plan(const std::string& text,
                                         const std::filesystem::path& file);
/// Reads and parses a plan file; InputError names the file when it cannot be read.
[[nodiscard]] PlanDescription load_plan(const std::filesystem::path& file);

/// Stage name and the fraction of the whole run done (0..1), for a progress bar.
using PlanProgress = std::function<void(const std::string& stage, double fraction)>;

/// What run_plan did, in brief (the report holds the rest).
struct PlanSummary {
  std::size_t points = 0;              ///< the tissue's points
  std::size_t springs = 0;             ///< springs (spring elasticity)
  std::size_t prisms = 0;              ///< prisms
  int segments = 0;                    ///< bone segments
  int moved_segments = 0;              ///< segments a move moved
  double residual_force_before = 0.0;  ///< N
  double residual_force_after = 0.0;   ///< N
  MinimizeResult prediction;           ///< how the prediction went
  double max_displacement = 0.0;       ///< mm, skin
  double seconds = 0.0;                ///< s, the whole run
  std::filesystem::path report;        ///< report.json
  /// The skin over its columns, before and after (m): what the pictures show.
  std::vector<Triangle> skin_triangles;
  std::vector<Vec3> skin_before;  ///< the skin's scanned positions (m)
  std::vector<Vec3> skin_after;   ///< its predicted positions (m)
};

/// Runs the plan, writes skin_before/after.vtp, bone_before/after.vtp, tissue.vtu and
/// report.json into `out_dir` (created). Throws InputError for bad input, including
/// interpenetrating bone segments (naming them and the depth).
PlanSummary run_plan(const PlanDescription& plan, const std::filesystem::path& out_dir,
                     const PlanProgress& progress = {});

}  // namespace incise::planning
