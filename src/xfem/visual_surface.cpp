#include "incise/xfem/visual_surface.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <tuple>
#include <unordered_map>

#include "incise/core/clamped_floor.hpp"
#include "incise/core/error.hpp"
#include "incise/mesh/boundary.hpp"
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
  // Pieces of a cut surface may touch at a single point: such points are duplicated so the
  // soup becomes a polygon mesh (orientations, already consistent, are kept).
  if (!PMP::is_polygon_soup_a_polygon_mesh(polygons)) {
    PMP::orient_polygon_soup(cgal_points, polygons);
  }
  CgalMesh mesh;
  PMP::polygon_soup_to_polygon_mesh(cgal_points, polygons, mesh);
  return mesh;
}

/// Where pieces of a cut surface touch at one point (split tetrahedra round a mesh edge in
/// separate fans, a waiting one between them: to_cgal gives each fan its own copy of the
/// point), each copy is drawn a millionth of the way towards the middle of its own fan. The
/// fans then no longer touch, which corefinement needs (a surface that does not intersect
/// itself), and the picture is not cut between them, where the physics is not either.
void separate_touching_fans(CgalMesh& cut) {
  std::map<std::array<double, 3>, std::vector<CgalMesh::Vertex_index>> at;
  for (const auto v : cut.vertices()) {
    const Point& p = cut.point(v);
    at[{p.x(), p.y(), p.z()}].push_back(v);
  }
  std::vector<std::pair<CgalMesh::Vertex_index, Point>> moves;
  for (const auto& [place, copies] : at) {
    if (copies.size() < 2) {
      continue;
    }
    for (const auto v : copies) {
      Vec3 middle = Vec3::Zero();
      int faces = 0;
      for (const auto f : CGAL::faces_around_target(cut.halfedge(v), cut)) {
        if (f == CgalMesh::null_face()) {
          continue;
        }
        for (const auto corner : CGAL::vertices_around_face(cut.halfedge(f), cut)) {
          middle += to_vec(cut.point(corner)) / 3.0;
        }
        ++faces;
      }
      if (faces == 0) {
        continue;
      }
      const Vec3 p(place[0], place[1], place[2]);
      const Vec3 moved = p + 1e-6 * (middle / faces - p);
      moves.emplace_back(v, Point(moved.x(), moved.y(), moved.z()));
    }
  }
  for (const auto& [v, p] : moves) {
    cut.point(v) = p;
  }
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

/// Whether a triangle has (next to) no area: its height over its longest edge below 1e-9 of
/// that edge (collinear corners, or two corners at one place).
bool is_flat(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double longest =
      std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return !((b - a).cross(c - a).norm() > 1e-9 * longest) || !(longest > 0.0);
}

}  // namespace

std::size_t remove_coincident_pairs(std::vector<Triangle>& triangles,
                                    std::vector<std::uint8_t>& on_cut) {
  // The same three points facing both ways enclose nothing: a piece of cut surface whose two
  // sides the welds and the nodes that carry them could not tell apart. Both go.
  std::map<std::array<VertexId, 3>, std::vector<std::size_t>> by_corners;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    std::array<VertexId, 3> key = triangles[t];
    std::sort(key.begin(), key.end());
    by_corners[key].push_back(t);
  }
  std::vector<bool> remove(triangles.size(), false);
  const auto same_direction = [](const Triangle& a, const Triangle& b) {
    for (int shift = 0; shift < 3; ++shift) {
      if (a[0] == b[static_cast<std::size_t>(shift)] &&
          a[1] == b[static_cast<std::size_t>((shift + 1) % 3)]) {
        return true;
      }
    }
    return false;
  };
  std::size_t removed = 0;
  for (const auto& [key, list] : by_corners) {
    std::vector<std::size_t> forward;
    std::vector<std::size_t> backward;
    for (std::size_t t : list) {
      (same_direction(triangles[t], triangles[list[0]]) ? forward : backward).push_back(t);
    }
    const std::size_t pairs = std::min(forward.size(), backward.size());
    for (std::size_t k = 0; k < pairs; ++k) {
      remove[forward[k]] = true;
      remove[backward[k]] = true;
    }
    removed += pairs;
  }
  if (removed == 0) {
    return 0;
  }
  std::size_t kept = 0;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (!remove[t]) {
      triangles[kept] = triangles[t];
      on_cut[kept] = on_cut[t];
      ++kept;
    }
  }
  triangles.resize(kept);
  on_cut.resize(kept);
  return removed;
}

std::size_t flip_flat_triangles(std::span<const Vec3> points, std::vector<Triangle>& triangles,
                                std::vector<std::uint8_t>& on_cut) {
  // A triangle with collinear corners (corefinement leaves some where a cut runs along a
  // visual edge) is flipped with its neighbour across its longest edge: the two become the
  // neighbour split at the flat triangle's middle corner, the same surface with no flat piece.
  std::size_t flips = 0;
  for (int pass = 0; pass < 8; ++pass) {
    std::map<std::pair<VertexId, VertexId>, std::size_t> directed;
    for (std::size_t t = 0; t < triangles.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) {
        directed[{triangles[t][k], triangles[t][(k + 1) % 3]}] = t;
      }
    }
    const auto at = [&](VertexId v) -> const Vec3& { return points[static_cast<std::size_t>(v)]; };
    std::vector<bool> touched(triangles.size(), false);
    std::size_t flipped_now = 0;
    for (std::size_t t = 0; t < triangles.size(); ++t) {
      const Triangle tri = triangles[t];
      if (touched[t] || !is_flat(at(tri[0]), at(tri[1]), at(tri[2]))) {
        continue;
      }
      // u -> v the longest edge, m the corner opposite it.
      std::size_t longest = 0;
      double length = -1.0;
      for (std::size_t k = 0; k < 3; ++k) {
        const double l = (at(tri[(k + 1) % 3]) - at(tri[k])).squaredNorm();
        if (l > length) {
          length = l;
          longest = k;
        }
      }
      const VertexId u = tri[longest];
      const VertexId v = tri[(longest + 1) % 3];
      const VertexId m = tri[(longest + 2) % 3];
      const auto across = directed.find({v, u});
      if (across == directed.end() || touched[across->second] || across->second == t) {
        continue;
      }
      const std::size_t n = across->second;
      VertexId w = kInvalidId;
      for (VertexId corner : triangles[n]) {
        if (corner != u && corner != v) {
          w = corner;
        }
      }
      if (w == kInvalidId || w == m || directed.contains({m, w}) || directed.contains({w, m})) {
        continue;  // the new edge exists already: flipping would make it non-manifold
      }
      if (is_flat(at(m), at(u), at(w)) || is_flat(at(w), at(v), at(m))) {
        continue;  // no better (w at m's place: the lips' two points there)
      }
      triangles[t] = {m, u, w};
      triangles[n] = {w, v, m};
      on_cut[t] = on_cut[n];  // both now lie in the neighbour's plane
      touched[t] = touched[n] = true;
      ++flipped_now;
    }
    flips += flipped_now;
    if (flipped_now == 0) {
      break;
    }
  }
  return flips;
}

std::size_t count_flat_triangles(std::span<const Vec3> points,
                                 std::span<const Triangle> triangles) {
  std::size_t flat = 0;
  for (const Triangle& t : triangles) {
    flat += is_flat(points[static_cast<std::size_t>(t[0])], points[static_cast<std::size_t>(t[1])],
                    points[static_cast<std::size_t>(t[2])])
                ? 1
                : 0;
  }
  return flat;
}

std::string closed_manifold_problem(std::span<const Vec3> points,
                                    std::span<const Triangle> triangles,
                                    const SurfaceEdgeCheck& allowed, std::size_t allowed_flat) {
  const SurfaceEdgeCheck edges = check_surface_edges(triangles);
  if (!cut_kept_boundary(allowed, edges)) {
    return fmt::format("{} open, {} non-manifold and {} misoriented edges", edges.open_edges,
                       edges.nonmanifold_edges, edges.misoriented_edges);
  }
  const std::size_t flat = count_flat_triangles(points, triangles);
  return flat <= allowed_flat ? std::string() : fmt::format("{} triangles with no area", flat);
}

namespace {

/// Crossings this close to an end (a share of the edge) are the cutter's record of a cut
/// through that vertex (XfemCutter puts them 1e-9 along).
constexpr double kAtVertex = 1e-8;

/// Where an output point is and what carries it: points that would move together merge.
struct PointKey {
  double x, y, z;
  Tet nodes;
  /// In a split tetrahedron, the side's element (1: the second): where its nodes are tied
  /// (not yet copied), both sides' points have the same carriers, yet belong to two lips.
  int side;
  auto operator<=>(const PointKey&) const = default;
};

}  // namespace

struct VisualSurface::Corefined {
  CgalMesh visual;
  CgalMesh cut;
};

struct VisualSurface::CgalCache {
  CgalMesh original;
  /// Boxes of the original's faces that intersect others of its faces (a surface from the
  /// wild may): corefinement's inputs must not intersect themselves where they meet.
  std::vector<CGAL::Bbox_3> self_crossings;
  std::unique_ptr<CGAL::Side_of_triangle_mesh<CgalMesh, Kernel>> inside;  ///< closed ones only
};

VisualSurface::VisualSurface(const TetMesh& mesh, std::vector<Vec3> points,
                             std::vector<Triangle> triangles)
    : cgal_(std::make_unique<CgalCache>()),
      rest_mesh_(std::vector<Vec3>(mesh.rest_positions().begin(), mesh.rest_positions().end()),
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
  {
    // A surface from the wild may come with flat triangles: flipped away once, here, so that
    // every picture can be held to having none.
    std::vector<std::uint8_t> marks(original_triangles_.size(), 0);
    flip_flat_triangles(original_points_, original_triangles_, marks);
  }
  closed_ = is_watertight(original_triangles_);
  cgal_->original = to_cgal(original_points_, original_triangles_);
  original_edges_ = check_surface_edges(original_triangles_);
  original_flat_ = count_flat_triangles(original_points_, original_triangles_);
  {
    std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> crossing;
    PMP::self_intersections(cgal_->original, std::back_inserter(crossing));
    for (const auto& [f, g] : crossing) {
      for (const auto face : {f, g}) {
        cgal_->self_crossings.push_back(PMP::face_bbox(face, cgal_->original));
      }
    }
  }
  if (closed_) {
    cgal_->inside =
        std::make_unique<CGAL::Side_of_triangle_mesh<CgalMesh, Kernel>>(cgal_->original);
  }
  for (const BoundaryFace& face : boundary_faces(rest_mesh_)) {
    std::array<VertexId, 3> key = face.vertices;
    std::sort(key.begin(), key.end());
    rest_boundary_.insert(key);
    for (std::size_t k = 0; k < 3; ++k) {
      rest_boundary_edges_.insert(edge_key(key[k], key[(k + 1) % 3]));
    }
  }
  point_cell_ = std::max(1e6 * nudge_, 1e-12);  // the mean edge length of the physics mesh
  for (std::size_t i = 0; i < original_points_.size(); ++i) {
    const Vec3& q = original_points_[i];
    point_cells_[point_cell_of(q)].push_back(i);
  }
  rest_points_ = original_points_;
  triangles_ = original_triangles_;
  on_cut_.assign(triangles_.size(), 0);
  embedding_.resize(rest_points_.size());
  for (std::size_t i = 0; i < rest_points_.size(); ++i) {
    bool outside = false;
    const TetId tet = locate(rest_points_[i], &outside);
    if (outside) {
      ++outside_;
      reach_ = std::max(reach_, std::sqrt(squared_distance_to_tet(rest_points_[i],
                                                                  rest_corners(rest_mesh_, tet))));
    }
    embedding_[i] = embed(mesh, nullptr, rest_points_[i], Vec3::Zero(), Vec3::Zero());
  }
}

VisualSurface::~VisualSurface() = default;

TetId VisualSurface::locate(const Vec3& p, bool* outside) const {
  // The original surface's points are located again after every cut: remember them.
  const std::array<double, 3> key{p.x(), p.y(), p.z()};
  if (const auto found = located_.find(key); found != located_.end()) {
    if (outside != nullptr) {
      *outside = found->second.second;
    }
    return found->second.first;
  }
  bool is_outside = false;
  const TetId tet = locate_uncached(p, is_outside);
  located_.emplace(key, std::pair(tet, is_outside));
  if (outside != nullptr) {
    *outside = is_outside;
  }
  return tet;
}

TetId VisualSurface::locate_uncached(const Vec3& p, bool& is_outside) const {
  std::vector<TetId> near;
  const Vec3 tiny = Vec3::Constant(nudge_);
  grid_->query(p - tiny, p + tiny, near);
  std::sort(near.begin(), near.end());  // the same answer whatever the grid's order
  for (TetId t : near) {
    const auto x = rest_corners(rest_mesh_, t);
    if (locate_in_tet(p, x[0], x[1], x[2], x[3]) != TetLocation::kOutside) {
      is_outside = false;
      return t;
    }
  }
  is_outside = true;
  // Outside the body: the nearest tetrahedron, searched in growing boxes.
  TetId best = kInvalidId;
  double best_distance = std::numeric_limits<double>::infinity();
  for (double radius = grid_->cell_size();; radius *= 2.0) {
    near.clear();
    grid_->query(p - Vec3::Constant(radius), p + Vec3::Constant(radius), near);
    std::sort(near.begin(), near.end());
    for (TetId t : near) {
      const double distance = squared_distance_to_tet(p, rest_corners(rest_mesh_, t));
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
                               const Vec3& inward, const Vec3& side, bool* side_b) const {
  // The tetrahedron is the one just inside the triangle p is a corner of (p itself may lie on
  // a face or edge several tetrahedra share, split and whole: the triangle's own one is the
  // one whose cut bounds it), and the side is read a little further, towards `side`.
  const Vec3 within = p + nudge_ * inward;
  bool outside = false;
  TetId rest = locate(cutter != nullptr ? within : p, &outside);
  if (outside && cutter != nullptr) {
    // Outside the body near the cut, the nearest tetrahedron may lie across the cut: a point
    // follows the nearest split tetrahedron within the surface's reach instead, on its side of
    // that tetrahedron's (extended) cut, as the band past the boundary cuts the surface.
    const double nearest = std::sqrt(squared_distance_to_tet(p, rest_corners(rest_mesh_, rest)));
    const double radius = nearest + reach_;
    std::vector<TetId> near;
    grid_->query(p - Vec3::Constant(radius), p + Vec3::Constant(radius), near);
    std::sort(near.begin(), near.end());
    double best = radius;
    for (TetId t : near) {
      if (!cutter->cut_of(t)) {
        continue;
      }
      const double distance = std::sqrt(squared_distance_to_tet(p, rest_corners(rest_mesh_, t)));
      if (distance <= best) {
        best = distance;
        rest = t;
      }
    }
  }
  const auto x = rest_corners(rest_mesh_, rest);
  TetId element = rest;
  if (cutter != nullptr && cutter->cut_of(rest)) {
    const TetId second = cutter->second_element(rest);
    if (second != kInvalidId) {
      element = on_side_b(x, *cutter->cut_of(rest), within + nudge_ * side) ? second : rest;
    }
  }
  if (side_b != nullptr) {
    *side_b = element != rest;
  }
  Embedding embedding;
  embedding.nodes = mesh.tet(element);
  embedding.weights = barycentric_coordinates(p, x[0], x[1], x[2], x[3]);
  return embedding;
}

void VisualSurface::follow(const TetMesh& mesh, const XfemCutter& cutter) {
  // Only split tetrahedra change the picture: the lips can part only there. (Pieces of cut in
  // tetrahedra the blade has entered but not crossed would be two sheets on the same points,
  // back to back between lips carried by the same nodes: they enclose nothing, cannot be seen
  // and would make the surface non-manifold; the picture opens where the physics does.)
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
  std::vector<std::uint64_t> edge_of_point;  // the mesh edge each cut point lies on
  for (std::size_t t = 0; t < rest_mesh_.tet_count(); ++t) {
    const auto& cut = cutter.cut_of(static_cast<TetId>(t));
    if (!cut) {
      continue;
    }
    const Tet& tet = rest_mesh_.tet(static_cast<TetId>(t));
    const auto x = rest_corners(rest_mesh_, static_cast<TetId>(t));
    std::vector<VertexId> polygon;
    for (int k : cut_polygon_edges(x, *cut)) {
      const auto& edge = tet_local::kEdges[static_cast<std::size_t>(k)];
      const auto i = static_cast<std::size_t>(edge[0]);
      const auto j = static_cast<std::size_t>(edge[1]);
      const double along = cut->crossing[static_cast<std::size_t>(k)];
      // A cut through a vertex (the cutter records it a hair along each edge from there) meets
      // every edge there at the vertex itself: one point, not one a rounding error from the
      // next on each edge (they would leave flat triangles wherever the picture meets them).
      const std::size_t at_vertex = along <= kAtVertex ? i : (along >= 1.0 - kAtVertex ? j : 4);
      const std::uint64_t key =
          at_vertex < 4 ? edge_key(tet[at_vertex], tet[at_vertex]) : edge_key(tet[i], tet[j]);
      const auto [slot, added] =
          crossing_point.try_emplace(key, static_cast<VertexId>(cut_points.size()));
      if (added) {
        cut_points.push_back(at_vertex < 4 ? x[at_vertex] : (1.0 - along) * x[i] + along * x[j]);
        edge_of_point.push_back(key);
      }
      if (polygon.empty() || (polygon.back() != slot->second && polygon.front() != slot->second)) {
        polygon.push_back(slot->second);
      }
    }
    for (std::size_t m = 1; m + 1 < polygon.size(); ++m) {
      cut_triangles.push_back({polygon[0], polygon[m], polygon[m + 1]});
    }
  }
  // The band past the boundary also keeps the cut's rim off a visual surface that lies on
  // the body's boundary (the body's own surface): corefinement then meets a crossing, not
  // two nearly coplanar triangles.
  if (closed_) {
    add_skirt(cut_points, cut_triangles, edge_of_point);
  }
  Corefined pair;
  pair.visual = cgal_->original;
  pair.cut = to_cgal(cut_points, cut_triangles);
  separate_touching_fans(pair.cut);
  // Corefinement asks for surfaces that do not intersect themselves (else it may throw,
  // crash or never return): real visual surfaces sometimes do (SOFA's liver-smooth.obj), and
  // a skirt round a sharp rim may. Both are checked where they would meet; a cut that fails
  // is not corefined, and the picture keeps its last cut.
  if (!cut_triangles.empty()) {
    if (!corefinable(pair)) {
      ++failures_;
      last_failure_ =
          "the cut surface intersects itself, or the visual surface where the cut "
          "meets it: not corefined";
      return;
    }
    try {
      PMP::corefine(pair.visual, pair.cut, CGAL::parameters::throw_on_self_intersection(true));
    } catch (const std::exception& error) {  // CGAL's failures, its constraint intersections
      ++failures_;
      last_failure_ = std::string("corefinement failed: ") + error.what();
      return;
    }
  }
  // Built aside: a picture that does not come out closed and 2-manifold (as the original
  // was), with no flat triangle, is not taken; the last good one stays.
  std::vector<Vec3> last_points = std::move(rest_points_);
  std::vector<Triangle> last_triangles = std::move(triangles_);
  std::vector<std::uint8_t> last_on_cut = std::move(on_cut_);
  std::vector<Embedding> last_embedding = std::move(embedding_);
  std::string problem;
  try {
    rebuild(mesh, cutter, pair);
    problem = closed_manifold_problem(rest_points_, triangles_, original_edges_, original_flat_);
  } catch (const std::exception& error) {
    problem = error.what();
  }
  if (!problem.empty()) {
    rest_points_ = std::move(last_points);
    triangles_ = std::move(last_triangles);
    on_cut_ = std::move(last_on_cut);
    embedding_ = std::move(last_embedding);
    ++failures_;
    last_failure_ = problem;
    return;
  }
  ++revision_;
}

bool VisualSurface::corefinable(const Corefined& pair) const {
  // Corefinement only works on the triangles where the two surfaces meet (CGAL checks those
  // for self-intersection when asked to throw on them): elsewhere a surface may touch itself.
  // The cut surface does, where the split tetrahedra round a mesh edge form separate fans
  // (a waiting tetrahedron between them): their triangles share the edge's crossing point but
  // orient_polygon_soup gives each fan its own copy of it. So only self-intersections whose
  // faces' boxes reach the other surface's faces stop the update.
  std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> crossing;
  PMP::self_intersections(pair.cut, std::back_inserter(crossing));
  std::vector<CGAL::Bbox_3> cut_crossings;
  for (const auto& [f, g] : crossing) {
    for (const auto face : {f, g}) {
      cut_crossings.push_back(PMP::face_bbox(face, pair.cut));
    }
  }
  const auto meets = [](std::span<const CGAL::Bbox_3> boxes, const CgalMesh& surface) {
    if (boxes.empty()) {
      return false;
    }
    for (const auto face : surface.faces()) {
      const CGAL::Bbox_3 box = PMP::face_bbox(face, surface);
      for (const CGAL::Bbox_3& other : boxes) {
        if (CGAL::do_overlap(box, other)) {
          return true;
        }
      }
    }
    return false;
  };
  return !meets(cut_crossings, pair.visual) && !meets(cgal_->self_crossings, pair.cut);
}

void VisualSurface::rebuild(const TetMesh& mesh, const XfemCutter& cutter, const Corefined& pair) {
  const CgalMesh& visual = pair.visual;
  const CgalMesh& cut_surface = pair.cut;
  const auto* inside = cgal_->inside.get();
  std::map<PointKey, VertexId> index;
  rest_points_.clear();
  triangles_.clear();
  on_cut_.clear();
  embedding_.clear();
  const auto add_point = [&](const Vec3& p, const Vec3& inward, const Vec3& side) {
    bool side_b = false;
    const Embedding embedding = embed(mesh, &cutter, p, inward, side, &side_b);
    PointKey key{
        p.x(), p.y(), p.z(), {kInvalidId, kInvalidId, kInvalidId, kInvalidId}, side_b ? 1 : 0};
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
      triangle[k] = add_point(p[k], (centre - p[k]).normalized(), Vec3::Zero());
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
        const Vec3 inward = (centre - p[k]).normalized();
        side_a[k] = add_point(p[k], inward, -normal);
        side_b[k] = add_point(p[k], inward, normal);
      }
      triangles_.push_back(side_a);
      triangles_.push_back({side_b[0], side_b[2], side_b[1]});
      on_cut_.push_back(1);
      on_cut_.push_back(1);
    }
  }
  tidy();
  weld_near_points();
  remove_coincident_pairs(triangles_, on_cut_);
  split_non_manifold(mesh);
  flip_flat_triangles(rest_points_, triangles_, on_cut_);
  close_flat_pockets();
}

void VisualSurface::close_flat_pockets() {
  // A flat triangle (u, v, m), m on u-v, whose neighbour across u-v is (v, u, w) with w at
  // m's place (two points one place apart only by their carriers, as where a cut face meets
  // the other side's point on a seam) encloses nothing: w is m, and the two go. (Flipping
  // cannot help there: it would join m to w by an edge with no length.)
  const auto at = [&](VertexId v) -> const Vec3& {
    return rest_points_[static_cast<std::size_t>(v)];
  };
  for (int pass = 0; pass < 8; ++pass) {
    std::map<std::pair<VertexId, VertexId>, std::size_t> directed;
    for (std::size_t t = 0; t < triangles_.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) {
        directed[{triangles_[t][k], triangles_[t][(k + 1) % 3]}] = t;
      }
    }
    std::vector<VertexId> into(rest_points_.size());
    std::iota(into.begin(), into.end(), VertexId{0});
    std::vector<bool> gone(triangles_.size(), false);
    bool any = false;
    for (std::size_t t = 0; t < triangles_.size(); ++t) {
      const Triangle& tri = triangles_[t];
      if (gone[t] || !is_flat(at(tri[0]), at(tri[1]), at(tri[2]))) {
        continue;
      }
      for (std::size_t k = 0; k < 3; ++k) {
        const VertexId u = tri[k];
        const VertexId v = tri[(k + 1) % 3];
        const VertexId m = tri[(k + 2) % 3];
        const auto across = directed.find({v, u});
        if (across == directed.end() || gone[across->second] || across->second == t) {
          continue;
        }
        VertexId w = kInvalidId;
        for (VertexId corner : triangles_[across->second]) {
          w = corner != u && corner != v ? corner : w;
        }
        if (w == kInvalidId || w == m || into[static_cast<std::size_t>(w)] != w ||
            into[static_cast<std::size_t>(m)] != m ||
            (at(w) - at(m)).norm() > 1e-9 * (at(v) - at(u)).norm()) {
          continue;
        }
        into[static_cast<std::size_t>(w)] = m;
        gone[t] = gone[across->second] = true;
        any = true;
        break;
      }
    }
    if (!any) {
      return;
    }
    std::size_t kept = 0;
    for (std::size_t t = 0; t < triangles_.size(); ++t) {
      if (gone[t]) {
        continue;
      }
      Triangle tri = triangles_[t];
      for (VertexId& corner : tri) {
        corner = into[static_cast<std::size_t>(corner)];
      }
      triangles_[kept] = tri;
      on_cut_[kept] = on_cut_[t];
      ++kept;
    }
    triangles_.resize(kept);
    on_cut_.resize(kept);
  }
}

void VisualSurface::split_non_manifold(const TetMesh& mesh) {
  // Where lips touch (tied nodes carry both sides' points alike) or pieces meet along an
  // edge, an edge can be used by 2k triangles, k each way. Each triangle using it one way is
  // paired with the one it meets first turning about the edge into the solid it bounds (the
  // radial order); then every point is copied once per fan of triangles around it, so each
  // edge is used by exactly its pair: the same surface, a 2-manifold.
  using Edge = std::pair<VertexId, VertexId>;
  std::map<Edge, std::vector<std::size_t>> uses;  // half-edge ids 3 t + k
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      const VertexId a = triangles_[t][k];
      const VertexId b = triangles_[t][(k + 1) % 3];
      uses[{std::min(a, b), std::max(a, b)}].push_back(3 * t + k);
    }
  }
  const auto from = [&](std::size_t h) { return triangles_[h / 3][h % 3]; };
  const auto third = [&](std::size_t h) { return triangles_[h / 3][(h % 3 + 2) % 3]; };
  std::vector<std::size_t> twin(3 * triangles_.size(), ~std::size_t{0});
  bool any = false;
  for (const auto& [edge, half_edges] : uses) {
    std::vector<std::size_t> forward;
    std::vector<std::size_t> backward;
    for (std::size_t h : half_edges) {
      (from(h) == edge.first ? forward : backward).push_back(h);
    }
    if (forward.size() != backward.size() || forward.empty()) {
      return;  // open or misoriented: nothing to pair (the check says so)
    }
    if (half_edges.size() == 2) {
      twin[forward[0]] = backward[0];
      twin[backward[0]] = forward[0];
      continue;
    }
    any = true;
    // Angles of the triangles' half-planes about the edge, looking along it (u -> v); a
    // triangle using the edge u -> v bounds the solid at smaller angles, one using v -> u the
    // solid at larger ones. At equal angles (lips back to back, the gap between them outside)
    // the one using u -> v comes first, so each lip is paired with a triangle on its own side
    // and the lips part, rather than closing a solid of no thickness between them.
    const Vec3& u = rest_points_[static_cast<std::size_t>(edge.first)];
    const Vec3 d = (rest_points_[static_cast<std::size_t>(edge.second)] - u).normalized();
    const auto across = [&](std::size_t h) {
      const Vec3 w = rest_points_[static_cast<std::size_t>(third(h))] - u;
      return Vec3(w - w.dot(d) * d);
    };
    const Vec3 e0 = across(half_edges[0]).normalized();
    const Vec3 e1 = d.cross(e0);
    std::vector<std::pair<std::pair<double, int>, std::size_t>> order;
    for (std::size_t h : half_edges) {
      const Vec3 e = across(h);
      double angle = std::atan2(e.dot(e1), e.dot(e0));
      angle += angle < 0.0 ? 2.0 * std::numbers::pi : 0.0;
      order.push_back({{angle, from(h) == edge.first ? 0 : 1}, h});
    }
    std::sort(order.begin(), order.end());
    // Each u -> v triangle's twin: the nearest v -> u one before it (cyclically).
    std::vector<bool> taken(order.size(), false);
    for (std::size_t i = 0; i < order.size(); ++i) {
      if (order[i].first.second != 0) {
        continue;
      }
      for (std::size_t back = 1; back < order.size(); ++back) {
        const std::size_t j = (i + order.size() - back) % order.size();
        if (order[j].first.second == 1 && !taken[j]) {
          taken[j] = true;
          twin[order[i].second] = order[j].second;
          twin[order[j].second] = order[i].second;
          break;
        }
      }
    }
  }
  if (!any) {
    return;
  }
  // Fans: around the point a half-edge leaves, the next half-edge leaving it is the twin of
  // the one before it in its triangle.
  std::vector<VertexId> corner_point(3 * triangles_.size());
  std::vector<bool> seen(3 * triangles_.size(), false);
  std::vector<bool> point_used(rest_points_.size(), false);
  for (std::size_t start = 0; start < corner_point.size(); ++start) {
    if (seen[start]) {
      continue;
    }
    const VertexId original = from(start);
    VertexId point = original;
    if (point_used[static_cast<std::size_t>(original)]) {
      point = static_cast<VertexId>(rest_points_.size());  // another fan: a copy of the point
      rest_points_.push_back(rest_points_[static_cast<std::size_t>(original)]);
      embedding_.push_back(embedding_[static_cast<std::size_t>(original)]);
    }
    point_used[static_cast<std::size_t>(original)] = true;
    std::size_t h = start;
    do {
      seen[h] = true;
      corner_point[h] = point;
      const std::size_t before = 3 * (h / 3) + (h % 3 + 2) % 3;
      h = twin[before];
    } while (h != ~std::size_t{0} && h != start && !seen[h]);
  }
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      triangles_[t][k] = corner_point[3 * t + k];
    }
  }
  split_shared_edges(mesh, twin);
}

void VisualSurface::split_shared_edges(const TetMesh& mesh, std::span<const std::size_t> twin) {
  // After the fans are apart, a pair can still share its edge's two points with another pair:
  // where a cut reaches the visual surface along one of its edges, and the lips have not
  // parted at either end (the slit is a two-sided hole between the same two points). Such a
  // pair gets a point of its own in the edge's middle, carried as one of its ends is: each of
  // its two triangles is split in two there, and every edge is then used by one pair.
  using Edge = std::pair<VertexId, VertexId>;
  std::map<Edge, std::vector<std::size_t>> uses;
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      const VertexId a = triangles_[t][k];
      const VertexId b = triangles_[t][(k + 1) % 3];
      uses[{std::min(a, b), std::max(a, b)}].push_back(3 * t + k);
    }
  }
  std::vector<bool> split(triangles_.size(), false);
  for (const auto& [edge, half_edges] : uses) {
    if (half_edges.size() <= 2) {
      continue;
    }
    bool first_pair = true;
    for (const std::size_t h : half_edges) {
      const std::size_t g = twin[h];
      if (g == ~std::size_t{0} || g < h ||
          std::find(half_edges.begin(), half_edges.end(), g) == half_edges.end()) {
        continue;  // each pair once (from its lower half-edge); a lost twin: the check says so
      }
      if (std::exchange(first_pair, false) || split[h / 3] || split[g / 3]) {
        continue;  // the first pair keeps the edge (a triangle is split once per update)
      }
      split[h / 3] = split[g / 3] = true;
      const VertexId a = edge.first;
      const VertexId b = edge.second;
      const Vec3 middle = 0.5 * (rest_points_[static_cast<std::size_t>(a)] +
                                 rest_points_[static_cast<std::size_t>(b)]);
      Embedding carried = embedding_[static_cast<std::size_t>(a)];
      carried.weights = barycentric_coordinates(
          middle, mesh.rest_position(carried.nodes[0]), mesh.rest_position(carried.nodes[1]),
          mesh.rest_position(carried.nodes[2]), mesh.rest_position(carried.nodes[3]));
      const auto m = static_cast<VertexId>(rest_points_.size());
      rest_points_.push_back(middle);
      embedding_.push_back(carried);
      for (const std::size_t half : {h, g}) {
        const std::size_t t = half / 3;
        const std::size_t k = half % 3;
        const Triangle original = triangles_[t];
        Triangle first = original;
        Triangle second = original;
        first[(k + 1) % 3] = m;  // (from, m, third)
        second[k] = m;           // (m, to, third)
        triangles_[t] = first;
        triangles_.push_back(second);
        on_cut_.push_back(on_cut_[t]);
      }
    }
  }
}

void VisualSurface::add_skirt(std::vector<Vec3>& points, std::vector<Triangle>& triangles,
                              std::span<const std::uint64_t> edge_of_point) const {
  // The cut surface's edges on the body's boundary (not its front, which lies between split
  // and whole tetrahedra inside): the two mesh edges their ends cross span a boundary face.
  std::map<std::pair<VertexId, VertexId>, std::size_t> directed;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      directed[{triangles[t][k], triangles[t][(k + 1) % 3]}] = t;
    }
  }
  std::vector<std::pair<VertexId, VertexId>> rim;
  std::vector<Vec3> outward(points.size(), Vec3::Zero());
  for (const auto& [edge, t] : directed) {
    if (directed.contains({edge.second, edge.first})) {
      continue;
    }
    const Vec3& a = points[static_cast<std::size_t>(edge.first)];
    const Vec3& b = points[static_cast<std::size_t>(edge.second)];
    const Triangle& tri = triangles[t];
    const Vec3 normal =
        (points[static_cast<std::size_t>(tri[1])] - points[static_cast<std::size_t>(tri[0])])
            .cross(points[static_cast<std::size_t>(tri[2])] -
                   points[static_cast<std::size_t>(tri[0])]);
    const Vec3 out = (b - a).cross(normal).normalized();
    std::array<VertexId, 4> ends{};
    for (std::size_t k = 0; k < 2; ++k) {
      const std::uint64_t key =
          edge_of_point[static_cast<std::size_t>(k == 0 ? edge.first : edge.second)];
      ends[2 * k] = static_cast<VertexId>(key >> 32);
      ends[2 * k + 1] = static_cast<VertexId>(key & 0xffffffffu);
    }
    std::sort(ends.begin(), ends.end());
    std::array<VertexId, 3> face{};
    const auto last = std::unique(ends.begin(), ends.end());
    if (last - ends.begin() == 2) {
      // Both ends at vertices (a cut through them): the rim runs along a mesh edge.
      if (!rest_boundary_edges_.contains(edge_key(ends[0], ends[1]))) {
        continue;
      }
    } else {
      if (last - ends.begin() != 3) {
        continue;
      }
      std::copy(ends.begin(), last, face.begin());
      if (!rest_boundary_.contains(face)) {
        continue;
      }
    }
    rim.push_back(edge);
    outward[static_cast<std::size_t>(edge.first)] += out;
    outward[static_cast<std::size_t>(edge.second)] += out;
  }
  // Each rim point extruded once (shared by its two rim edges) past the visual surface, as far
  // as the surface sticks out at most; where band pieces would cross the cut surface or each
  // other (the rim's concave bends), their ends are drawn in, halving until they do not, and a
  // piece that still crosses is left out: corefinement needs a surface that does not intersect
  // itself.
  std::unordered_map<VertexId, std::size_t> far_index;  // rim point -> slot in far / length
  std::vector<VertexId> rim_points;
  for (const auto& [a, b] : rim) {
    for (VertexId v : {a, b}) {
      if (far_index.try_emplace(v, rim_points.size()).second) {
        rim_points.push_back(v);
      }
    }
  }
  std::vector<double> length(rim_points.size());
  for (std::size_t k = 0; k < rim_points.size(); ++k) {
    const Vec3& p = points[static_cast<std::size_t>(rim_points[k])];
    length[k] =
        std::min(std::max(3.0 * nearest_visual_distance(p), reach_), 2.0 * reach_) + 1e3 * nudge_;
  }
  const std::size_t first_far = points.size();
  points.resize(first_far + rim_points.size());
  const auto place = [&](std::size_t k) {
    const auto v = static_cast<std::size_t>(rim_points[k]);
    points[first_far + k] = points[v] + length[k] * outward[v].normalized();
  };
  for (std::size_t k = 0; k < rim_points.size(); ++k) {
    place(k);
  }
  const auto at = [&](VertexId v) -> const Vec3& { return points[static_cast<std::size_t>(v)]; };
  const auto crosses = [&](const Triangle& candidate, std::span<const Triangle> others) {
    for (const Triangle& other : others) {
      bool shares = false;
      for (VertexId v : candidate) {
        shares = shares || std::find(other.begin(), other.end(), v) != other.end();
      }
      if (!shares && triangles_intersect(at(candidate[0]), at(candidate[1]), at(candidate[2]),
                                         at(other[0]), at(other[1]), at(other[2]))) {
        return true;
      }
    }
    return false;
  };
  const std::size_t inside_count = triangles.size();
  std::vector<std::array<Triangle, 2>> band;
  for (const auto& [a, b] : rim) {
    const auto a_far = static_cast<VertexId>(first_far + far_index.at(a));
    const auto b_far = static_cast<VertexId>(first_far + far_index.at(b));
    band.push_back({Triangle{b, a, a_far}, Triangle{b, a_far, b_far}});
  }
  std::vector<Triangle> all;
  for (int round = 0; round < 8; ++round) {
    all.assign(triangles.begin(), triangles.begin() + static_cast<std::ptrdiff_t>(inside_count));
    for (const auto& piece : band) {
      all.push_back(piece[0]);
      all.push_back(piece[1]);
    }
    std::vector<bool> shrink(rim_points.size(), false);
    bool any = false;
    for (const auto& piece : band) {
      if (crosses(piece[0], all) || crosses(piece[1], all)) {
        shrink[static_cast<std::size_t>(piece[0][2]) - first_far] = true;
        shrink[static_cast<std::size_t>(piece[1][2]) - first_far] = true;
        any = true;
      }
    }
    if (!any) {
      break;
    }
    for (std::size_t k = 0; k < rim_points.size(); ++k) {
      if (shrink[k]) {
        length[k] *= 0.5;
        place(k);
      }
    }
  }
  for (const auto& piece : band) {
    if (!crosses(piece[0], all) && !crosses(piece[1], all)) {
      triangles.push_back(piece[0]);
      triangles.push_back(piece[1]);
    }
  }
}

std::array<long, 3> VisualSurface::point_cell_of(const Vec3& q) const {
  // 2^40 cells each way: far beyond any body, and room for the rings searched around it.
  constexpr long kFarthest = 1L << 40;
  return {clamped_floor(q.x() / point_cell_, -kFarthest, kFarthest),
          clamped_floor(q.y() / point_cell_, -kFarthest, kFarthest),
          clamped_floor(q.z() / point_cell_, -kFarthest, kFarthest)};
}

double VisualSurface::nearest_visual_distance(const Vec3& p) const {
  const auto centre = point_cell_of(p);
  double best = std::numeric_limits<double>::infinity();
  for (long ring = 0; ring < 1000; ++ring) {
    for (long i = -ring; i <= ring; ++i) {
      for (long j = -ring; j <= ring; ++j) {
        for (long k = -ring; k <= ring; ++k) {
          if (std::max({std::abs(i), std::abs(j), std::abs(k)}) != ring) {
            continue;
          }
          const auto found = point_cells_.find({centre[0] + i, centre[1] + j, centre[2] + k});
          if (found == point_cells_.end()) {
            continue;
          }
          for (std::size_t index : found->second) {
            best = std::min(best, (original_points_[index] - p).norm());
          }
        }
      }
    }
    // Points in further rings lie at least `ring` cells away.
    if (best <= static_cast<double>(ring) * point_cell_) {
      break;
    }
  }
  return std::isfinite(best) ? best : 0.0;
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

void VisualSurface::weld_near_points() {
  // Corefinement's constructed points can land a rounding error (1e-18 m) from a point made
  // elsewhere, and a point on a mesh face or edge may be carried from either side of it (its
  // triangles read its element a little inside themselves): the two ends of an edge that are
  // one point in all but rounding or carriers are welded, the first one's embedding carrying
  // both (the triangles between them, needles with no area, go). Lips' points at one place
  // are never joined by an edge, so they stay apart.
  const double near = 1e-9 * point_cell_;  // m
  std::vector<VertexId> into(rest_points_.size());
  std::iota(into.begin(), into.end(), VertexId{0});
  const auto find = [&](VertexId v) {
    while (into[static_cast<std::size_t>(v)] != v) {
      v = into[static_cast<std::size_t>(v)] =
          into[static_cast<std::size_t>(into[static_cast<std::size_t>(v)])];
    }
    return v;
  };
  bool welded = false;
  for (const Triangle& t : triangles_) {
    for (std::size_t k = 0; k < 3; ++k) {
      const VertexId a = find(t[k]);
      const VertexId b = find(t[(k + 1) % 3]);
      if (a == b ||
          (rest_points_[static_cast<std::size_t>(a)] - rest_points_[static_cast<std::size_t>(b)])
                  .norm() > near) {
        continue;
      }
      into[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
      welded = true;
    }
  }
  if (!welded) {
    return;
  }
  std::size_t kept = 0;
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    Triangle tri = triangles_[t];
    for (VertexId& v : tri) {
      v = find(v);
    }
    if (tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]) {
      triangles_[kept] = tri;
      on_cut_[kept] = on_cut_[t];
      ++kept;
    }
  }
  triangles_.resize(kept);
  on_cut_.resize(kept);
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

std::vector<std::pair<VertexId, double>> carriers(const VisualSurface& surface,
                                                  std::size_t triangle,
                                                  const std::array<double, 3>& barycentric) {
  std::vector<std::pair<VertexId, double>> result;
  const Triangle& corners = surface.triangles()[triangle];
  for (std::size_t c = 0; c < 3; ++c) {
    const Embedding& at = surface.embeddings()[static_cast<std::size_t>(corners[c])];
    for (std::size_t k = 0; k < 4; ++k) {
      const double weight = barycentric[c] * at.weights[k];
      if (weight == 0.0) {
        continue;
      }
      auto found = std::find_if(result.begin(), result.end(),
                                [&](const auto& entry) { return entry.first == at.nodes[k]; });
      if (found == result.end()) {
        result.emplace_back(at.nodes[k], weight);
      } else {
        found->second += weight;
      }
    }
  }
  return result;
}

}  // namespace incise
