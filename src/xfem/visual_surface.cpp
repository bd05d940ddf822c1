#include "incise/xfem/visual_surface.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <unordered_map>

#include "incise/core/error.hpp"
#include "incise/mesh/predicates.hpp"
#include "incise/xfem/element_cut.hpp"
#include "incise/xfem/xfem_cutter.hpp"

namespace incise {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalMesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;

Vec3 to_vec(const Point& p) {
  return {p.x(), p.y(), p.z()};
}

CgalMesh to_cgal(std::span<const Vec3> points, std::span<const Triangle> triangles) {
  std::vector<Point> cgal_points;
  cgal_points.reserve(points.size());
  for (const Vec3& p : points) {
    cgal_points.emplace_back(p.x(), p.y(), p.z());
  }
  std::vector<std::vector<std::size_t>> polygons;
  polygons.reserve(triangles.size());
  for (const Triangle& t : triangles) {
    polygons.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]),
                        static_cast<std::size_t>(t[2])});
  }
  CgalMesh mesh;
  PMP::polygon_soup_to_polygon_mesh(cgal_points, polygons, mesh);
  return mesh;
}

std::uint64_t edge_key(VertexId a, VertexId b) {
  return (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
         static_cast<std::uint32_t>(std::max(a, b));
}

std::array<Vec3, 4> corners_of(const TetMesh& mesh, TetId t) {
  const Tet& tet = mesh.tet(t);
  return {mesh.rest_position(tet[0]), mesh.rest_position(tet[1]), mesh.rest_position(tet[2]),
          mesh.rest_position(tet[3])};
}

/// m^2: squared distance from p to a closed tetrahedron (0 inside).
double squared_distance_to_tet(const Vec3& p, const std::array<Vec3, 4>& x) {
  const auto w = barycentric_coordinates(p, x[0], x[1], x[2], x[3]);
  if (*std::min_element(w.begin(), w.end()) >= 0.0) {
    return 0.0;
  }
  double best = std::numeric_limits<double>::infinity();
  for (const auto& face : tet_local::kFaces) {
    best = std::min(best, squared_distance_to_triangle(p, x[static_cast<std::size_t>(face[0])],
                                                       x[static_cast<std::size_t>(face[1])],
                                                       x[static_cast<std::size_t>(face[2])]));
  }
  return best;
}

/// Whether q lies on side b of a split tetrahedron's cut, read from the cut polygon's planes
/// (extended, so a point nudged just outside the tetrahedron still reads its side): one plane,
/// or two for a quad bent along its diagonal, where side b is the wedge between them when the
/// quad bends towards b and the rest of space when it bends away.
bool on_side_b(const std::array<Vec3, 4>& corners, const ElementCut& cut, const Vec3& q) {
  const std::vector<Vec3> polygon = cut_polygon(corners, cut);  // oriented from a to b
  const Vec3 n1 = (polygon[1] - polygon[0]).cross(polygon[2] - polygon[0]);
  const bool above1 = (q - polygon[0]).dot(n1) > 0.0;
  if (polygon.size() == 3) {
    return above1;
  }
  const Vec3 n2 = (polygon[2] - polygon[0]).cross(polygon[3] - polygon[0]);
  const bool above2 = (q - polygon[0]).dot(n2) > 0.0;
  const bool bends_to_b = (polygon[3] - polygon[0]).dot(n1) > 0.0;
  return bends_to_b ? (above1 && above2) : (above1 || above2);
}

/// Where an output point is and what carries it: points that would move together merge.
struct PointKey {
  double x, y, z;
  Tet nodes;
  auto operator<=>(const PointKey&) const = default;
};

}  // namespace

VisualSurface::VisualSurface(const TetMesh& mesh, std::vector<Vec3> points,
                             std::vector<Triangle> triangles)
    : rest_mesh_(std::vector<Vec3>(mesh.rest_positions().begin(), mesh.rest_positions().end()),
                 std::vector<Tet>(mesh.tets().begin(), mesh.tets().end())),
      original_points_(std::move(points)),
      original_triangles_(std::move(triangles)) {
  for (const Triangle& t : original_triangles_) {
    for (VertexId v : t) {
      if (v < 0 || static_cast<std::size_t>(v) >= original_points_.size()) {
        throw InputError("visual surface: a triangle uses point " + std::to_string(v) +
                         ", which does not exist");
      }
    }
  }
  for (const Vec3& p : original_points_) {
    if (!p.allFinite()) {
      throw InputError("visual surface: a point is not finite");
    }
  }
  grid_ = std::make_unique<TetGrid>(rest_mesh_);
  double length = 0.0;
  for (std::size_t e = 0; e < rest_mesh_.edge_count(); ++e) {
    const auto& [a, b] = rest_mesh_.edge(static_cast<EdgeId>(e));
    length += (rest_mesh_.rest_position(a) - rest_mesh_.rest_position(b)).norm();
  }
  nudge_ = 1e-6 * length / static_cast<double>(std::max<std::size_t>(1, rest_mesh_.edge_count()));
  closed_ = is_watertight(original_triangles_);
  rest_points_ = original_points_;
  triangles_ = original_triangles_;
  on_cut_.assign(triangles_.size(), 0);
  embedding_.resize(rest_points_.size());
  for (std::size_t i = 0; i < rest_points_.size(); ++i) {
    bool outside = false;
    (void)locate(rest_points_[i], &outside);
    outside_ += outside ? 1 : 0;
    embedding_[i] = embed(mesh, nullptr, rest_points_[i], Vec3::Zero());
  }
}

VisualSurface::~VisualSurface() = default;

TetId VisualSurface::locate(const Vec3& p, bool* outside) const {
  std::vector<TetId> near;
  const Vec3 tiny = Vec3::Constant(nudge_);
  grid_->query(p - tiny, p + tiny, near);
  std::sort(near.begin(), near.end());  // the same answer whatever the grid's order
  for (TetId t : near) {
    const auto x = corners_of(rest_mesh_, t);
    if (locate_in_tet(p, x[0], x[1], x[2], x[3]) != TetLocation::kOutside) {
      if (outside != nullptr) {
        *outside = false;
      }
      return t;
    }
  }
  if (outside != nullptr) {
    *outside = true;
  }
  // Outside the body: the nearest tetrahedron, searched in growing boxes.
  TetId best = kInvalidId;
  double best_distance = std::numeric_limits<double>::infinity();
  for (double radius = grid_->cell_size();; radius *= 2.0) {
    near.clear();
    grid_->query(p - Vec3::Constant(radius), p + Vec3::Constant(radius), near);
    std::sort(near.begin(), near.end());
    for (TetId t : near) {
      const double distance = squared_distance_to_tet(p, corners_of(rest_mesh_, t));
      if (distance < best_distance) {
        best_distance = distance;
        best = t;
      }
    }
    if ((best != kInvalidId && std::sqrt(best_distance) <= radius) ||
        near.size() == rest_mesh_.tet_count()) {
      break;
    }
  }
  INCISE_ASSERT(best != kInvalidId, "a mesh with tetrahedra has a nearest one");
  return best;
}

Embedding VisualSurface::embed(const TetMesh& mesh, const XfemCutter* cutter, const Vec3& p,
                               const Vec3& towards) const {
  const TetId rest = locate(p);
  const auto x = corners_of(rest_mesh_, rest);
  TetId element = rest;
  if (cutter != nullptr && cutter->cut_of(rest)) {
    const TetId second = cutter->second_element(rest);
    if (second != kInvalidId) {
      const Vec3 q = p + nudge_ * towards;
      element = on_side_b(x, *cutter->cut_of(rest), q) ? second : rest;
    }
  }
  Embedding embedding;
  embedding.nodes = mesh.tet(element);
  embedding.weights = barycentric_coordinates(p, x[0], x[1], x[2], x[3]);
  return embedding;
}

void VisualSurface::follow(const TetMesh& mesh, const XfemCutter& cutter) {
  if (cutter.stats().elements_split == split_seen_) {
    return;
  }
  split_seen_ = cutter.stats().elements_split;

  // The cut surface the physics sees: each split tetrahedron's polygon through its edge
  // crossings, a crossing shared by every tetrahedron around its edge, oriented from side a
  // to side b.
  std::vector<Vec3> cut_points;
  std::vector<Triangle> cut_triangles;
  std::unordered_map<std::uint64_t, VertexId> crossing_point;
  for (std::size_t t = 0; t < rest_mesh_.tet_count(); ++t) {
    const auto& cut = cutter.cut_of(static_cast<TetId>(t));
    if (!cut) {
      continue;
    }
    const Tet& tet = rest_mesh_.tet(static_cast<TetId>(t));
    const auto x = corners_of(rest_mesh_, static_cast<TetId>(t));
    std::vector<VertexId> polygon;
    for (int k : cut_polygon_edges(x, *cut)) {
      const auto& edge = tet_local::kEdges[static_cast<std::size_t>(k)];
      const auto i = static_cast<std::size_t>(edge[0]);
      const auto j = static_cast<std::size_t>(edge[1]);
      const auto [slot, added] = crossing_point.try_emplace(
          edge_key(tet[i], tet[j]), static_cast<VertexId>(cut_points.size()));
      if (added) {
        const double along = cut->crossing[static_cast<std::size_t>(k)];
        cut_points.push_back((1.0 - along) * x[i] + along * x[j]);
      }
      polygon.push_back(slot->second);
    }
    for (std::size_t m = 1; m + 1 < polygon.size(); ++m) {
      cut_triangles.push_back({polygon[0], polygon[m], polygon[m + 1]});
    }
  }

  CgalMesh visual = to_cgal(original_points_, original_triangles_);
  CgalMesh cut_surface = to_cgal(cut_points, cut_triangles);
  std::unique_ptr<CGAL::Side_of_triangle_mesh<CgalMesh, Kernel>> inside;
  CgalMesh original;
  if (closed_) {
    original = visual;
    inside = std::make_unique<CGAL::Side_of_triangle_mesh<CgalMesh, Kernel>>(original);
  }
  if (!cut_triangles.empty()) {
    PMP::corefine(visual, cut_surface);
  }

  std::map<PointKey, VertexId> index;
  rest_points_.clear();
  triangles_.clear();
  on_cut_.clear();
  embedding_.clear();
  const auto add_point = [&](const Vec3& p, const Vec3& towards) {
    const Embedding embedding = embed(mesh, &cutter, p, towards);
    PointKey key{p.x(), p.y(), p.z(), {kInvalidId, kInvalidId, kInvalidId, kInvalidId}};
    for (std::size_t k = 0; k < 4; ++k) {
      if (std::abs(embedding.weights[k]) > 1e-12) {
        key.nodes[k] = embedding.nodes[k];
      }
    }
    std::sort(key.nodes.begin(), key.nodes.end());
    const auto [slot, added] = index.try_emplace(key, static_cast<VertexId>(rest_points_.size()));
    if (added) {
      rest_points_.push_back(p);
      embedding_.push_back(embedding);
    }
    return slot->second;
  };
  const auto face_points = [](const CgalMesh& m, CgalMesh::Face_index f) {
    std::array<Vec3, 3> points;
    std::size_t k = 0;
    for (const auto v : CGAL::vertices_around_face(m.halfedge(f), m)) {
      points[k++] = to_vec(m.point(v));
    }
    return points;
  };
  for (const auto f : visual.faces()) {
    const auto p = face_points(visual, f);
    const Vec3 centre = (p[0] + p[1] + p[2]) / 3.0;
    Triangle triangle{};
    for (std::size_t k = 0; k < 3; ++k) {
      triangle[k] = add_point(p[k], (centre - p[k]).normalized());
    }
    triangles_.push_back(triangle);
    on_cut_.push_back(0);
  }
  if (inside) {
    for (const auto f : cut_surface.faces()) {
      const auto p = face_points(cut_surface, f);
      const Vec3 centre = (p[0] + p[1] + p[2]) / 3.0;
      if ((*inside)(Point(centre.x(), centre.y(), centre.z())) != CGAL::ON_BOUNDED_SIDE) {
        continue;
      }
      const Vec3 normal = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
      // Side a's piece is closed by the cut face as it is (its normal points from a to b),
      // side b's by the reversed face.
      Triangle side_a{};
      Triangle side_b{};
      for (std::size_t k = 0; k < 3; ++k) {
        side_a[k] = add_point(p[k], -normal);
        side_b[k] = add_point(p[k], normal);
      }
      triangles_.push_back(side_a);
      triangles_.push_back({side_b[0], side_b[2], side_b[1]});
      on_cut_.push_back(1);
      on_cut_.push_back(1);
    }
  }
  tidy();
}

void VisualSurface::tidy() {
  // A triangle whose corners rounded onto one point has no area: it goes, with its two
  // opposite edges, which keeps every other edge's pairing.
  std::vector<Triangle> kept;
  std::vector<std::uint8_t> kept_on_cut;
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    const Triangle& tri = triangles_[t];
    if (tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]) {
      kept.push_back(tri);
      kept_on_cut.push_back(on_cut_[t]);
    }
  }
  triangles_ = std::move(kept);
  on_cut_ = std::move(kept_on_cut);

  // Where the picture's cut runs a little past the physics' front (a vertex of a crossed edge
  // held by a whole tetrahedron already has its copy), the two sides' points at one place are
  // carried by different nodes and the surface would be open along that seam: such points,
  // on edges used once, are welded into one (the first one's embedding carries it).
  std::map<std::pair<VertexId, VertexId>, int> directed;
  for (const Triangle& tri : triangles_) {
    for (std::size_t k = 0; k < 3; ++k) {
      ++directed[{tri[k], tri[(k + 1) % 3]}];
    }
  }
  std::map<std::array<double, 3>, VertexId> first_at;
  std::vector<VertexId> weld(rest_points_.size());
  for (std::size_t v = 0; v < weld.size(); ++v) {
    weld[v] = static_cast<VertexId>(v);
  }
  bool welded = false;
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (count == 1 && reverse != directed.end() && reverse->second == 1) {
      continue;
    }
    for (VertexId v : {edge.first, edge.second}) {
      const Vec3& p = rest_points_[static_cast<std::size_t>(v)];
      const auto [slot, added] = first_at.try_emplace({p.x(), p.y(), p.z()}, v);
      if (!added && slot->second != v) {
        if (std::getenv("INCISE_DEBUG_WELD") != nullptr) {
          std::fprintf(stderr, "weld %d -> %d at %g %g %g\n", v, slot->second, p.x(), p.y(), p.z());
        }
        weld[static_cast<std::size_t>(v)] = slot->second;
        welded = true;
      }
    }
  }
  if (!welded) {
    return;
  }
  kept.clear();
  kept_on_cut.clear();
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    Triangle tri = triangles_[t];
    for (VertexId& v : tri) {
      v = weld[static_cast<std::size_t>(v)];
    }
    if (tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]) {
      kept.push_back(tri);
      kept_on_cut.push_back(on_cut_[t]);
    }
  }
  triangles_ = std::move(kept);
  on_cut_ = std::move(kept_on_cut);
}

std::vector<Vec3> VisualSurface::positions(std::span<const Vec3> nodes) const {
  std::vector<Vec3> result(embedding_.size());
  for (std::size_t i = 0; i < embedding_.size(); ++i) {
    Vec3 p = Vec3::Zero();
    for (std::size_t k = 0; k < 4; ++k) {
      p += embedding_[i].weights[k] * nodes[static_cast<std::size_t>(embedding_[i].nodes[k])];
    }
    result[i] = p;
  }
  return result;
}

double enclosed_volume(std::span<const Vec3> points, std::span<const Triangle> triangles) {
  double six = 0.0;
  for (const Triangle& t : triangles) {
    const Vec3& a = points[static_cast<std::size_t>(t[0])];
    const Vec3& b = points[static_cast<std::size_t>(t[1])];
    const Vec3& c = points[static_cast<std::size_t>(t[2])];
    six += a.dot(b.cross(c));
  }
  return six / 6.0;
}

bool is_watertight(std::span<const Triangle> triangles) {
  std::map<std::pair<VertexId, VertexId>, int> directed;
  for (const Triangle& t : triangles) {
    for (std::size_t k = 0; k < 3; ++k) {
      ++directed[{t[k], t[(k + 1) % 3]}];
    }
  }
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (reverse == directed.end() || reverse->second != count) {
      return false;
    }
  }
  return true;
}

}  // namespace incise
