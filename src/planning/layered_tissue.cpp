#include "incise/planning/layered_tissue.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "incise/core/error.hpp"
#include "incise/planning/prism.hpp"
#include "nearest_triangle.hpp"

namespace incise::planning {

std::size_t LayeredTissue::count(PointKind k) const {
  return static_cast<std::size_t>(std::count(kind.begin(), kind.end(), k));
}

namespace {

void check_options(const LayeredTissueOptions& options) {
  if (options.layers < 1 || options.layers > 64) {
    throw InputError("layers must be between 1 and 64 (got " + std::to_string(options.layers) +
                     ")");
  }
  if (options.materials.size() != 1 &&
      options.materials.size() != static_cast<std::size_t>(options.layers)) {
    throw InputError("give one material for all layers or one per layer (" +
                     std::to_string(options.layers) + "), not " +
                     std::to_string(options.materials.size()));
  }
  for (const LayerMaterial& m : options.materials) {
    if (!(m.young_modulus > 0.0) || !(m.density > 0.0) || !std::isfinite(m.young_modulus) ||
        !std::isfinite(m.density)) {
      throw InputError("layer materials need a positive, finite young_modulus and density");
    }
  }
  if (!(options.skin_prestrain > -0.5 && options.skin_prestrain < 1.0)) {
    throw InputError("skin_prestrain must lie in (-0.5, 1)");
  }
  if (!(options.nonlinearity >= 0.0) || !(options.volume_weight >= 0.0) ||
      !std::isfinite(options.nonlinearity) || !std::isfinite(options.volume_weight)) {
    throw InputError("nonlinearity and volume_weight must be finite and not negative");
  }
  for (const LayerMaterial& m : options.materials) {
    if (!(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5)) {
      throw InputError("layer materials need a poisson_ratio in (-1, 0.5)");
    }
  }
  if (!(options.skin_thickness >= 0.0) || !std::isfinite(options.skin_thickness)) {
    throw InputError("skin_thickness must be finite and not negative");
  }
  if (options.elasticity == TissueElasticity::kContinuum && options.skin_prestrain != 0.0 &&
      options.skin_thickness == 0.0) {
    throw InputError(
        "skin_prestrain needs a skin membrane with continuum elasticity: give skin_thickness");
  }
  if (!(options.max_thickness > options.min_thickness) || !(options.min_thickness >= 0.0)) {
    throw InputError("max_thickness must exceed min_thickness (>= 0)");
  }
}

/// Splits the prism over skin triangle t (its columns) into three tetrahedra: with the corners
/// a < b < c by column, (a0 b0 c0 c1), (a0 b0 b1 c1), (a0 a1 b1 c1) (0: the prism's lower
/// layer, 1: its upper), which cuts the side between columns u < v by the diagonal u0-v1
/// whichever prism it bounds.
void split_into_tets(const Triangle& t, Prism& prism) {
  std::array<std::uint8_t, 3> order = {0, 1, 2};
  std::sort(order.begin(), order.end(),
            [&](std::uint8_t i, std::uint8_t j) { return t[i] < t[j]; });
  const std::uint8_t a = order[0];
  const std::uint8_t b = order[1];
  const std::uint8_t c = order[2];
  const auto up = [](std::uint8_t i) { return static_cast<std::uint8_t>(i + 3); };
  prism.tets[0].corners = {a, b, c, up(c)};
  prism.tets[1].corners = {a, b, up(b), up(c)};
  prism.tets[2].corners = {a, up(a), up(b), up(c)};
}

/// The skin membrane's springs (the continuum's layer-0 springs): k = E t (A1 + A2) / l0^2 over
/// the one or two skin triangles beside the edge. On a mesh of equilateral triangles this gives
/// the membrane an equibiaxial stiffness E t / (1 - nu) with the lattice's nu = 1/3, so a
/// pre-strain e pulls with the tension E t e / (1 - nu) (N/m) whatever the layers. Stores the
/// volume t (A1 + A2) in `spring_volume`; the caller multiplies by E / l0^2.
void set_skin_membrane(const LayeredTissue& tissue, double thickness,
                       const std::map<std::pair<int, int>, int>& spring_of,
                       std::vector<double>& spring_volume) {
  for (const Triangle& t : tissue.skin_triangles) {
    const Vec3& p0 = tissue.rest[static_cast<std::size_t>(tissue.point(t[0], 0))];
    const Vec3& p1 = tissue.rest[static_cast<std::size_t>(tissue.point(t[1], 0))];
    const Vec3& p2 = tissue.rest[static_cast<std::size_t>(tissue.point(t[2], 0))];
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    for (std::size_t e = 0; e < 3; ++e) {
      const auto found =
          spring_of.find(std::minmax(tissue.point(t[e], 0), tissue.point(t[(e + 1) % 3], 0)));
      if (found != spring_of.end()) {
        spring_volume[static_cast<std::size_t>(found->second)] += thickness * area;
      }
    }
  }
}

/// See set_tet_rest_shapes; `orient` (at build) orders each tetrahedron's corners positively
/// instead of refusing a negative one.
std::size_t set_tet_rest_shapes(LayeredTissue& tissue, std::span<const Vec3> rest, bool orient) {
  std::size_t slivers = 0;
  for (std::size_t p = 0; p < tissue.prisms.size(); ++p) {
    Prism& prism = tissue.prisms[p];
    double size = 0.0;
    for (std::size_t i = 1; i < 6; ++i) {
      size = std::max(size, (rest[static_cast<std::size_t>(prism.points[i])] -
                             rest[static_cast<std::size_t>(prism.points[0])])
                                .norm());
    }
    for (PrismTet& tet : prism.tets) {
      if (!orient && tet.rest.volume == 0.0) {
        continue;  // empty since the build
      }
      const Corners c = tet_corners(prism, tet, rest);
      double volume = (c[1] - c[0]).dot((c[2] - c[0]).cross(c[3] - c[0])) / 6.0;
      if (orient && volume < 0.0) {
        std::swap(tet.corners[2], tet.corners[3]);
        volume = -volume;
      }
      // A tetrahedron of a column of no thickness (or a degenerate skin triangle) is empty.
      if (orient && !(volume > 1e-9 * size * size * size)) {
        tet.rest = TetRestShape{};
        continue;
      }
      if (!(volume > 0.0) &&
          std::abs(tet_quality(tet_corners(prism, tet, tissue.rest))) < kSliverQuality) {
        tet.rest = TetRestShape{};  // see LayeredTissue::sliver_tets
        ++slivers;
        continue;
      }
      if (!(volume > 0.0)) {
        const Corners scanned = tet_corners(prism, tet, tissue.rest);
        const Vec3 centre = 250.0 * (scanned[0] + scanned[1] + scanned[2] + scanned[3]);  // mm
        throw InputError(fmt::format(
            "the tissue's rest shape would invert a tetrahedron of prism {} (layer {}, points {} "
            "{} {} {} {} {}, at ({:.1f}, {:.1f}, {:.1f}) mm, scanned volume {:.3g} mm^3, "
            "rest shift up to {:.2f} mm): lower the load (gravity, skin pre-strain) or stiffen "
            "the layers",
            p, prism.layer, prism.points[0], prism.points[1], prism.points[2], prism.points[3],
            prism.points[4], prism.points[5], centre.x(), centre.y(), centre.z(),
            1e9 *
                (scanned[1] - scanned[0])
                    .dot((scanned[2] - scanned[0]).cross(scanned[3] - scanned[0])) /
                6.0,
            1e3 * std::max({(c[0] - scanned[0]).norm(), (c[1] - scanned[1]).norm(),
                            (c[2] - scanned[2]).norm(), (c[3] - scanned[3]).norm()})));
      }
      tet.rest = tet_rest_shape(tet_corners(prism, tet, rest), static_cast<std::int64_t>(p));
    }
  }
  tissue.sliver_tets += slivers;
  return slivers;
}

/// Whether the bone side of a skin triangle (`ends`, its columns' bone ends) has turned over
/// against the skin side (`tops`), or collapsed to under a hundredth of its area: the prisms
/// of the column's last layer are then inside out or flat.
bool folded(const Triangle& t, std::span<const Vec3> tops, std::span<const Vec3> ends) {
  const auto at = [&](std::span<const Vec3> x, std::size_t i) -> const Vec3& {
    return x[static_cast<std::size_t>(t[i])];
  };
  const Vec3 skin_normal = (at(tops, 1) - at(tops, 0)).cross(at(tops, 2) - at(tops, 0));
  const Vec3 bone_normal = (at(ends, 1) - at(ends, 0)).cross(at(ends, 2) - at(ends, 0));
  return !(skin_normal.dot(bone_normal) > 0.1 * skin_normal.norm() * bone_normal.norm()) ||
         !(bone_normal.norm() > 0.01 * skin_normal.norm());
}

}  // namespace

LayeredTissue build_layered_tissue(const SurfaceMesh& skin, const SurfaceMesh& bone,
                                   const LayeredTissueOptions& options) {
  check_options(options);
  if (skin.triangles.empty() || bone.triangles.empty()) {
    throw InputError("the layered tissue model needs a skin and a bone surface with triangles");
  }
  LayeredTissue tissue;
  tissue.layers = options.layers;
  // Tissue triangles: those without an over-long edge, over the vertices they use.
  std::vector<double> edge_lengths;
  edge_lengths.reserve(3 * skin.triangles.size());
  auto edge_length = [&](const Triangle& t, int e) {
    return (skin.points[static_cast<std::size_t>(t[static_cast<std::size_t>(e)])] -
            skin.points[static_cast<std::size_t>(t[static_cast<std::size_t>((e + 1) % 3)])])
        .norm();
  };
  for (const Triangle& t : skin.triangles) {
    for (int e = 0; e < 3; ++e) {
      edge_lengths.push_back(edge_length(t, e));
    }
  }
  std::nth_element(edge_lengths.begin(),
                   edge_lengths.begin() + static_cast<std::ptrdiff_t>(edge_lengths.size() / 2),
                   edge_lengths.end());
  const double max_edge =
      options.max_edge > 0.0 ? options.max_edge : 5.0 * edge_lengths[edge_lengths.size() / 2];
  std::vector<int> column_of_vertex(skin.points.size(), -1);
  for (const Triangle& t : skin.triangles) {
    if (edge_length(t, 0) > max_edge || edge_length(t, 1) > max_edge ||
        edge_length(t, 2) > max_edge) {
      ++tissue.skin_triangles_dropped;
      continue;
    }
    Triangle out{};
    for (int c = 0; c < 3; ++c) {
      int& column = column_of_vertex[static_cast<std::size_t>(t[static_cast<std::size_t>(c)])];
      if (column < 0) {
        column = static_cast<int>(tissue.column_skin_vertex.size());
        tissue.column_skin_vertex.push_back(t[static_cast<std::size_t>(c)]);
      }
      out[static_cast<std::size_t>(c)] = column;
    }
    tissue.skin_triangles.push_back(out);
  }
  if (tissue.skin_triangles.empty()) {
    throw InputError("every skin triangle has an edge longer than max_edge");
  }
  tissue.columns = static_cast<int>(tissue.column_skin_vertex.size());
  // Columns on the open border of the tissue triangles: the tissue leaves the scan there.
  std::vector<char> on_border(static_cast<std::size_t>(tissue.columns), 0);
  {
    std::map<std::pair<int, int>, int> uses;
    for (const Triangle& t : tissue.skin_triangles) {
      for (int e = 0; e < 3; ++e) {
        ++uses[std::minmax(t[static_cast<std::size_t>(e)],
                           t[static_cast<std::size_t>((e + 1) % 3)])];
      }
    }
    for (const auto& [edge, count] : uses) {
      if (count == 1) {
        on_border[static_cast<std::size_t>(edge.first)] = 1;
        on_border[static_cast<std::size_t>(edge.second)] = 1;
      }
    }
  }
  tissue.law.nonlinearity = options.nonlinearity;
  tissue.elasticity = options.elasticity;
  tissue.volume_weight = options.volume_weight;
  tissue.skin_prestrain = options.skin_prestrain;
  const int layers = options.layers;
  const std::size_t points = static_cast<std::size_t>(tissue.columns) * (layers + 1);
  tissue.rest.resize(points);
  tissue.kind.assign(points, PointKind::kSoft);
  tissue.mass.assign(points, 0.0);
  tissue.column_bone_triangle.resize(static_cast<std::size_t>(tissue.columns));

  // Columns: from each skin vertex to its nearest bone point, split evenly into layers.
  const NearestTriangle nearest(bone.points, bone.triangles);
  const auto columns = static_cast<std::size_t>(tissue.columns);
  std::vector<Vec3> tops(columns);
  std::vector<Vec3> ends(columns);
  std::vector<PointKind> column_kinds(columns, PointKind::kSoft);
  for (std::size_t c = 0; c < columns; ++c) {
    tops[c] = skin.points[static_cast<std::size_t>(tissue.column_skin_vertex[c])];
    const NearestTriangle::Hit hit = nearest.closest(tops[c]);
    ends[c] = hit.point;
    tissue.column_bone_triangle[c] = hit.triangle;
    const double thickness = (hit.point - tops[c]).norm();
    if (thickness > options.max_thickness || on_border[c] != 0) {
      column_kinds[c] = PointKind::kBoundary;
    } else if (thickness < options.min_thickness) {
      column_kinds[c] = PointKind::kBone;
    }
  }
  for (const Triangle& t : tissue.skin_triangles) {
    const bool soft = std::any_of(t.begin(), t.end(), [&](int c) {
      return column_kinds[static_cast<std::size_t>(c)] == PointKind::kSoft;
    });
    tissue.folded_triangles += soft && folded(t, tops, ends) ? 1 : 0;
  }
  for (std::size_t c = 0; c < columns; ++c) {
    for (int k = 0; k <= layers; ++k) {
      const auto p = static_cast<std::size_t>(tissue.point(static_cast<int>(c), k));
      tissue.rest[p] = tops[c] + (static_cast<double>(k) / layers) * (ends[c] - tops[c]);
      tissue.kind[p] =
          k == layers && column_kinds[c] == PointKind::kSoft ? PointKind::kBone : column_kinds[c];
    }
  }

  // Springs: found again by their end points when prisms hand out volume.
  std::map<std::pair<int, int>, int> spring_of;
  auto add_spring = [&](int a, int b, SpringSet set, int layer) {
    const auto key = std::minmax(a, b);
    if (spring_of.count(key) != 0) {
      return;
    }
    spring_of[key] = static_cast<int>(tissue.springs.size());
    Spring s;
    s.a = a;
    s.b = b;
    s.set = set;
    s.layer = layer;
    s.rest_length =
        (tissue.rest[static_cast<std::size_t>(a)] - tissue.rest[static_cast<std::size_t>(b)])
            .norm();
    tissue.springs.push_back(s);
  };
  const bool continuum = options.elasticity == TissueElasticity::kContinuum;
  for (const Triangle& t : tissue.skin_triangles) {
    for (int k = 0; k < layers; ++k) {
      for (int e = 0; e < 3; ++e) {
        const int u = t[static_cast<std::size_t>(e)];
        const int v = t[static_cast<std::size_t>((e + 1) % 3)];
        if (continuum) {
          if (k == 0 && options.skin_thickness > 0.0) {
            add_spring(tissue.point(u, 0), tissue.point(v, 0), SpringSet::kLayer, 0);
          }
          continue;
        }
        add_spring(tissue.point(u, k), tissue.point(v, k), SpringSet::kLayer, k);
        add_spring(tissue.point(u, k), tissue.point(u, k + 1), SpringSet::kConnecting, k);
        add_spring(tissue.point(u, k), tissue.point(v, k + 1), SpringSet::kDiagonal, k);
        add_spring(tissue.point(v, k), tissue.point(u, k + 1), SpringSet::kDiagonal, k);
      }
      Prism prism;
      for (int i = 0; i < 3; ++i) {
        prism.points[static_cast<std::size_t>(i)] = tissue.point(t[static_cast<std::size_t>(i)], k);
        prism.points[static_cast<std::size_t>(i + 3)] =
            tissue.point(t[static_cast<std::size_t>(i)], k + 1);
      }
      prism.layer = k;
      PrismPoints corners;
      for (int i = 0; i < 6; ++i) {
        corners[static_cast<std::size_t>(i)] =
            tissue.rest[static_cast<std::size_t>(prism.points[static_cast<std::size_t>(i)])];
      }
      prism.rest_volume = prism_volume(corners);
      if (continuum) {
        split_into_tets(t, prism);
      }
      tissue.prisms.push_back(prism);
    }
  }

  // Stiffness k = E V_s / l0^2 with V_s the volume a spring stands for: each prism gives a
  // fifteenth of its volume to each of its 15 springs (6 layer, 3 connecting, 6 diagonal), so
  // the springs share the body's volume (a spring stretched by e stores E V_s e^2 / 2). Point
  // masses: a sixth of each prism's mass.
  auto material_of = [&](int layer) -> const LayerMaterial& {
    return options.materials.size() == 1 ? options.materials[0]
                                         : options.materials[static_cast<std::size_t>(layer)];
  };
  std::vector<double> spring_volume(tissue.springs.size(), 0.0);
  for (Prism& prism : tissue.prisms) {
    const LayerMaterial& material = material_of(prism.layer);
    const double volume = std::abs(prism.rest_volume);
    for (int i = 0; i < 6; ++i) {
      tissue.mass[static_cast<std::size_t>(prism.points[static_cast<std::size_t>(i)])] +=
          material.density * volume / 6.0;
    }
    if (continuum) {
      prism.material =
          stable_neo_hookean(lame_parameters(material.young_modulus, material.poisson_ratio));
      continue;
    }
    const auto& p = prism.points;
    const std::array<std::pair<int, int>, 15> edges = {{{p[0], p[1]},
                                                        {p[1], p[2]},
                                                        {p[2], p[0]},
                                                        {p[3], p[4]},
                                                        {p[4], p[5]},
                                                        {p[5], p[3]},
                                                        {p[0], p[3]},
                                                        {p[1], p[4]},
                                                        {p[2], p[5]},
                                                        {p[0], p[4]},
                                                        {p[1], p[3]},
                                                        {p[1], p[5]},
                                                        {p[2], p[4]},
                                                        {p[2], p[3]},
                                                        {p[0], p[5]}}};
    for (const auto& [a, b] : edges) {
      const auto found = spring_of.find(std::minmax(a, b));
      if (found != spring_of.end()) {
        spring_volume[static_cast<std::size_t>(found->second)] += volume / 15.0;
      }
    }
  }
  if (continuum) {
    set_skin_membrane(tissue, options.skin_thickness, spring_of, spring_volume);
  }
  for (std::size_t s = 0; s < tissue.springs.size(); ++s) {
    Spring& spring = tissue.springs[s];
    const LayerMaterial& material = material_of(spring.layer);
    const double length = std::max(spring.rest_length, options.min_thickness / layers);
    spring.stiffness = material.young_modulus * spring_volume[s] / (length * length);
    if (spring.set == SpringSet::kLayer && spring.layer == 0) {
      // Skin pre-strain: the scanned length is the stretched one.
      spring.rest_length /= 1.0 + options.skin_prestrain;
    }
  }
  // Springs between two fixed points never act: dropped.
  std::erase_if(tissue.springs, [&](const Spring& s) {
    return tissue.kind[static_cast<std::size_t>(s.a)] != PointKind::kSoft &&
           tissue.kind[static_cast<std::size_t>(s.b)] != PointKind::kSoft;
  });
  std::erase_if(tissue.springs, [](const Spring& s) { return !(s.rest_length > 0.0); });
  std::erase_if(tissue.prisms, [&](const Prism& prism) {
    return std::none_of(prism.points.begin(), prism.points.end(), [&](int p) {
      return tissue.kind[static_cast<std::size_t>(p)] == PointKind::kSoft;
    });
  });
  if (continuum) {
    (void)set_tet_rest_shapes(tissue, tissue.rest, true);
  }
  return tissue;
}

double tet_quality(const Corners& c) {
  const double volume = (c[1] - c[0]).dot((c[2] - c[0]).cross(c[3] - c[0])) / 6.0;
  double squares = 0.0;
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = i + 1; j < 4; ++j) {
      squares += (c[i] - c[j]).squaredNorm();
    }
  }
  const double rms = std::sqrt(squares / 6.0);
  return rms > 0.0 ? 6.0 * std::sqrt(2.0) * volume / (rms * rms * rms) : 0.0;
}

Corners tet_corners(const Prism& prism, const PrismTet& tet, std::span<const Vec3> x) {
  Corners corners;
  for (std::size_t i = 0; i < 4; ++i) {
    corners[i] = x[static_cast<std::size_t>(prism.points[tet.corners[i]])];
  }
  return corners;
}

std::size_t set_tet_rest_shapes(LayeredTissue& tissue, std::span<const Vec3> rest) {
  return set_tet_rest_shapes(tissue, rest, false);
}

}  // namespace incise::planning
