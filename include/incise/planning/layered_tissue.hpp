#pragma once
// The multi-layer soft-tissue model of Teschner, Girod and Girod: soft-tissue points in layers
// between the skin and the bone, joined by springs in three sets (layer springs along the
// triangulated skin structure of each layer, connecting springs between layers, diagonal
// springs across the side faces) that together bound prismatic volume elements.
//
// Built from a skin surface and a bone surface: every skin vertex starts a column towards its
// nearest point on the bone; the column holds `layers` soft-tissue layers and ends on the bone
// in a bone point. Skin triangles with an edge longer than `max_edge` (the flat caps that
// close scans) are left out. Columns on the skin's open border, and columns thicker than
// `max_thickness`, are where the tissue leaves the scanned region: their points are boundary
// points, fixed in space. Columns thinner than `min_thickness` lie on the bone and move with
// it.
//
// Two elasticities over the same prisms:
//   kSprings    the seed's: layer, connecting and diagonal springs with k = E V_s / l0^2, the
//               skin layer's springs pre-strained. A spring lattice carries the elasticity
//               tensor its directions make (sum of k l^2 n n n n), so its stiffness changes with
//               the prisms' aspect ratio: results drift as layers are added (BENCHMARKS.md).
//   kContinuum  each prism split into three linear tetrahedra of stable Neo-Hookean material
//               (physics/stable_neo_hookean: smooth through inversion, which a bone's step
//               under thin tissue can force) with Young's modulus and Poisson's ratio per layer,
//               and the skin a pre-strained membrane of springs of its own thickness on the outer
//               surface. Both pass the patch test, so results converge as layers are added (tested
//               against Lame's thick spherical shell).
// The volume term, gravity and masses are the same in both.
//
// Units: SI inside (m, kg, N, Pa); plans and their outputs convert from and to millimetres.

#include <cstdint>
#include <span>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/physics/corotational.hpp"
#include "incise/physics/stable_neo_hookean.hpp"
#include "incise/planning/spring_law.hpp"

namespace incise::planning {

enum class PointKind : std::uint8_t { kSoft, kBone, kBoundary };
enum class SpringSet : std::uint8_t { kLayer, kConnecting, kDiagonal };
enum class TissueElasticity : std::uint8_t { kSprings, kContinuum };

/// A spring of the seed's tissue between two points.
struct Spring {
  int a = 0;                          ///< one end (a point index)
  int b = 0;                          ///< the other end
  double rest_length = 0.0;           ///< m
  double stiffness = 0.0;             ///< N/m
  SpringSet set = SpringSet::kLayer;  ///< which of the seed's three sets it belongs to
  int layer = 0;  ///< the layer it lies in (layer springs) or starts from (the others)
};

/// One of a prism's three tetrahedra (continuum elasticity): its corners as indices 0-5 into
/// the prism's points, positively oriented at rest, and its rest shape. An empty one (a column
/// of no thickness) has zero rest volume and acts on nothing.
struct PrismTet {
  std::array<std::uint8_t, 4> corners{};  ///< indices 0-5 into the prism's points
  TetRestShape rest;                      ///< rest volume (m^3) and shape gradients
};

/// A column's piece between two layers: a skin triangle's three columns, one layer apart.
struct Prism {
  std::array<int, 6> points{};  ///< bottom (outer layer) triangle, then the top (inner) one
  double rest_volume = 0.0;     ///< m^3, signed (see prism.hpp)
  int layer = 0;                ///< its layer, 0 at the skin
  /// Continuum elasticity only: the prism split into three tetrahedra. The quadrilateral side
  /// between columns u < v is cut by its diagonal from u's lower-layer point to v's upper-layer
  /// one, so neighbouring prisms split their shared side alike and the tetrahedra conform.
  std::array<PrismTet, 3> tets{};
  NeoHookeanParameters material;  ///< its layer's material (continuum elasticity)
};

/// One soft-tissue layer's material (plan key `tissue.materials`).
struct LayerMaterial {
  double young_modulus = 1.5e4;  ///< Pa
  double density = 1050.0;       ///< kg/m^3
  double poisson_ratio = 0.45;   ///< continuum elasticity only (springs have their own, 1/4)
};

/// How the layered tissue is built between skin and bone (plan key `tissue`).
struct LayeredTissueOptions {
  int layers = 3;  ///< soft-tissue layers between skin and bone
  /// One per layer from the skin inwards, or one for all layers.
  std::vector<LayerMaterial> materials = {LayerMaterial{}};
  /// The default converges as layers are added; kSprings is the seed's model.
  TissueElasticity elasticity = TissueElasticity::kContinuum;
  double skin_prestrain = 0.0;  ///< initial strain of the skin layer's springs
  /// m: continuum elasticity's skin membrane (epidermis and dermis over the layers, with the
  /// outer layer's Young's modulus), which carries the pre-strain; 0: no membrane.
  double skin_thickness = 2e-3;
  double nonlinearity = 0.0;    ///< the spring law's a (spring_law.hpp)
  double volume_weight = 0.0;   ///< Pa: stiffness of the prisms' volume preservation
  double max_thickness = 0.03;  ///< m: thicker columns are boundary (fixed)
  double min_thickness = 2e-4;  ///< m: thinner columns move with the bone
  /// m: skin triangles with a longer edge are not tissue (the caps that close a scan's open
  /// end, fans across the neck) and are left out; 0 picks 5 x the median edge length.
  double max_edge = 0.0;
};

/// The seed's layered soft tissue between the skin and the bone: a column of points per skin
/// vertex, from the skin (layer 0) to its nearest bone point, joined by springs or by
/// prisms of three tetrahedra each. Positions in m, masses in kg.
struct LayeredTissue {
  int layers = 0;                          ///< soft-tissue layers per column
  int columns = 0;                         ///< one per skin vertex
  std::vector<Vec3> rest;                  ///< m: the scanned positions
  std::vector<PointKind> kind;             ///< per point: soft, on the bone or on the boundary
  std::vector<double> mass;                ///< kg
  std::vector<Spring> springs;             ///< spring elasticity (the seed's)
  std::vector<Prism> prisms;               ///< every column's pieces between layers
  std::vector<Triangle> skin_triangles;    ///< over columns
  std::vector<int> column_skin_vertex;     ///< the input skin vertex of each column
  std::size_t skin_triangles_dropped = 0;  ///< longer than max_edge
  /// Continuum elasticity: slivers (quality below kSliverQuality at the scan) that the
  /// equilibrium's rest shift would turn inside out, left empty instead: a flat tetrahedron of
  /// a folded column carries next to no volume, and a shift of a fraction of its height
  /// inverts it. The prism's other tetrahedra and its volume term still hold the column.
  std::size_t sliver_tets = 0;
  std::vector<int> column_bone_triangle;  ///< the bone triangle each column ends on
  /// Skin triangles with a soft column whose bone side (the columns' nearest bone points) is
  /// turned over against the skin side or collapsed to under a hundredth of its area: where
  /// the bone is concave under the skin or ends in a rim (the skull's base above the neck), the
  /// nearest points fold. Their last layer's tetrahedra are slivers or overlap their
  /// neighbours (each is still at rest in the scanned state).
  std::size_t folded_triangles = 0;
  SpringLaw law;                                             ///< the springs' law
  TissueElasticity elasticity = TissueElasticity::kSprings;  ///< springs or continuum
  double volume_weight = 0.0;                                ///< Pa
  double skin_prestrain = 0.0;  ///< the skin's initial strain (dimensionless)

  /// The point of column c at layer k (0: skin, layers: bone).
  [[nodiscard]] int point(int column, int layer) const { return column * (layers + 1) + layer; }
  /// A point's layer (0: skin).
  [[nodiscard]] int layer_of(int point) const { return point % (layers + 1); }
  /// A point's column.
  [[nodiscard]] int column_of(int point) const { return point / (layers + 1); }
  /// Points in all.
  [[nodiscard]] std::size_t point_count() const { return rest.size(); }
  /// Points of one kind.
  [[nodiscard]] std::size_t count(PointKind k) const;
};

/// Below this quality (tet_quality) a prism's tetrahedron is a sliver and left empty.
inline constexpr double kSliverQuality = 1e-2;

/// 6 sqrt(2) V / l^3 with l the root mean square of the six edges: 1 for a regular
/// tetrahedron, 0 for a flat one, negative for an inverted one. Pure.
[[nodiscard]] double tet_quality(const Corners& corners);

/// Builds the model; throws InputError on an empty surface or bad options.
[[nodiscard]] LayeredTissue build_layered_tissue(const SurfaceMesh& skin, const SurfaceMesh& bone,
                                                 const LayeredTissueOptions& options);

/// The corners of one of a prism's tetrahedra at positions x.
[[nodiscard]] Corners tet_corners(const Prism& prism, const PrismTet& tet, std::span<const Vec3> x);

/// Continuum elasticity: the tetrahedra's rest shapes from the given rest positions of every
/// point (the equilibrium initialisation moves the soft points' ones). Tetrahedra of no volume
/// are left empty, and so are slivers the rest positions would invert (returns how many, also
/// added to sliver_tets); throws InputError naming the prism and where it is if any other
/// tetrahedron would be inverted.
std::size_t set_tet_rest_shapes(LayeredTissue& tissue, std::span<const Vec3> rest);

}  // namespace incise::planning
