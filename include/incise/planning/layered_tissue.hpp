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
// Units: SI inside (m, kg, N, Pa); plans and their outputs convert from and to millimetres.

#include <cstdint>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/planning/spring_law.hpp"

namespace incise::planning {

enum class PointKind : std::uint8_t { kSoft, kBone, kBoundary };
enum class SpringSet : std::uint8_t { kLayer, kConnecting, kDiagonal };

struct Spring {
  int a = 0;
  int b = 0;
  double rest_length = 0.0;  ///< m
  double stiffness = 0.0;    ///< N/m
  SpringSet set = SpringSet::kLayer;
  int layer = 0;  ///< the layer it lies in (layer springs) or starts from (the others)
};

struct Prism {
  std::array<int, 6> points{};  ///< bottom (outer layer) triangle, then the top (inner) one
  double rest_volume = 0.0;     ///< m^3, signed (see prism.hpp)
  int layer = 0;
};

struct LayerMaterial {
  double young_modulus = 1.5e4;  ///< Pa
  double density = 1050.0;       ///< kg/m^3
};

struct LayeredTissueOptions {
  int layers = 3;  ///< soft-tissue layers between skin and bone
  /// One per layer from the skin inwards, or one for all layers.
  std::vector<LayerMaterial> materials = {LayerMaterial{}};
  double skin_prestrain = 0.0;  ///< initial strain of the skin layer's springs
  double nonlinearity = 0.0;    ///< the spring law's a (spring_law.hpp)
  double volume_weight = 0.0;   ///< Pa: stiffness of the prisms' volume preservation
  double max_thickness = 0.03;  ///< m: thicker columns are boundary (fixed)
  double min_thickness = 2e-4;  ///< m: thinner columns move with the bone
  /// m: skin triangles with a longer edge are not tissue (the caps that close a scan's open
  /// end, fans across the neck) and are left out; 0 picks 5 x the median edge length.
  double max_edge = 0.0;
};

struct LayeredTissue {
  int layers = 0;
  int columns = 0;         ///< one per skin vertex
  std::vector<Vec3> rest;  ///< m: the scanned positions
  std::vector<PointKind> kind;
  std::vector<double> mass;  ///< kg
  std::vector<Spring> springs;
  std::vector<Prism> prisms;
  std::vector<Triangle> skin_triangles;    ///< over columns
  std::vector<int> column_skin_vertex;     ///< the input skin vertex of each column
  std::size_t skin_triangles_dropped = 0;  ///< longer than max_edge
  std::vector<int> column_bone_triangle;   ///< nearest bone triangle of each column
  SpringLaw law;
  double volume_weight = 0.0;  ///< Pa
  double skin_prestrain = 0.0;

  /// The point of column c at layer k (0: skin, layers: bone).
  [[nodiscard]] int point(int column, int layer) const { return column * (layers + 1) + layer; }
  [[nodiscard]] int layer_of(int point) const { return point % (layers + 1); }
  [[nodiscard]] int column_of(int point) const { return point / (layers + 1); }
  [[nodiscard]] std::size_t point_count() const { return rest.size(); }
  [[nodiscard]] std::size_t count(PointKind k) const;
};

/// Builds the model; throws InputError on an empty surface or bad options.
[[nodiscard]] LayeredTissue build_layered_tissue(const SurfaceMesh& skin, const SurfaceMesh& bone,
                                                 const LayeredTissueOptions& options);

}  // namespace incise::planning
