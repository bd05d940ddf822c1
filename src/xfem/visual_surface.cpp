#include "incise/xfem/visual_surface.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
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

/// The part of the segment p0 -> p1 inside a tetrahedron (corners x, vertex ids `ids`): its
/// parameters along the segment and the face each end lies on (the local index of the corner
/// opposite it; -1 where the segment ends inside). A face's plane is taken through its corners
/// in increasing vertex id, so the two tetrahedra that share a face find the same point, bit
/// for bit, and the pieces of cut surface they make meet there.
struct SegmentClip {
  double enter = 0.0;
  double exit = 1.0;
  int enter_face = -1;
  int exit_face = -1;
};

std::optional<SegmentClip> clip_segment(const std::array<Vec3, 4>& x, const Tet& ids,
                                        const Vec3& p0, const Vec3& p1) {
  SegmentClip clip;
  for (int k = 0; k < 4; ++k) {
    std::array<int, 3> face{};
    for (int i = 0, m = 0; i < 4; ++i) {
      if (i != k) {
        face[static_cast<std::size_t>(m++)] = i;
      }
    }
    std::sort(face.begin(), face.end(), [&](int a, int b) {
      return ids[static_cast<std::size_t>(a)] < ids[static_cast<std::size_t>(b)];
    });
    const Vec3& a = x[static_cast<std::size_t>(face[0])];
    Vec3 normal =
        (x[static_cast<std::size_t>(face[1])] - a).cross(x[static_cast<std::size_t>(face[2])] - a);
    if (normal.dot(x[static_cast<std::size_t>(k)] - a) < 0.0) {
      normal = -normal;  // inside is positive
    }
    const double f0 = normal.dot(p0 - a);
    const double f1 = normal.dot(p1 - a);
    if (f0 < 0.0 && f1 < 0.0) {
      return std::nullopt;
    }
    if (f0 < 0.0 && f1 >= 0.0) {
      const double s = f0 / (f0 - f1);
      if (s > clip.enter) {
        clip.enter = s;
        clip.enter_face = k;
      }
    } else if (f1 < 0.0 && f0 >= 0.0) {
      const double s = f0 / (f0 - f1);
      if (s < clip.exit) {
        clip.exit = s;
        clip.exit_face = k;
      }
    }
  }
  if (!(clip.enter < clip.exit)) {
    return std::nullopt;
  }
  return clip;
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

struct VisualSurface::CgalCache {
  CgalMesh original;
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
  closed_ = is_watertight(original_triangles_);
  cgal_->original = to_cgal(original_points_, original_triangles_);
  if (closed_) {
    cgal_->inside =
        std::make_unique<CGAL::Side_of_triangle_mesh<CgalMesh, Kernel>>(cgal_->original);
  }
  for (const BoundaryFace& face : boundary_faces(rest_mesh_)) {
    std::array<VertexId, 3> key = face.vertices;
    std::sort(key.begin(), key.end());
    rest_boundary_.insert(key);
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
    embedding_[i] = embed(mesh, nullptr, rest_points_[i], Vec3::Zero());
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
                               const Vec3& towards) const {
  bool outside = false;
  TetId rest = locate(p, &outside);
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
  // Split tetrahedra change the picture, and so does the blade moving on inside tetrahedra it
  // has only partly crossed (the progressive part).
  const std::vector<TetId> front = cutter.front();
  if (cutter.stats().elements_split == split_seen_ &&
      (front.empty() || cutter.stats().moves == moves_seen_)) {
    return;
  }
  split_seen_ = cutter.stats().elements_split;
  moves_seen_ = cutter.stats().moves;

  // The cut surface the physics sees: each split tetrahedron's polygon through its edge
  // crossings, a crossing shared by every tetrahedron around its edge, oriented from side a
  // to side b; then the pieces the blade has cut in front of it. When CGAL cannot corefine
  // with the pieces in front (a walk that doubles back can leave pieces that meet others), the
  // picture is cut without them; when it cannot at all, the picture keeps its last cut.
  CgalMesh visual;
  CgalMesh cut_surface;
  bool corefined = false;
  for (const bool with_front : {true, false}) {
    if (!with_front && front.empty()) {
      break;
    }
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
        const auto [slot, added] = crossing_point.try_emplace(
            edge_key(tet[i], tet[j]), static_cast<VertexId>(cut_points.size()));
        if (added) {
          const double along = cut->crossing[static_cast<std::size_t>(k)];
          cut_points.push_back((1.0 - along) * x[i] + along * x[j]);
          edge_of_point.push_back(edge_key(tet[i], tet[j]));
        }
        polygon.push_back(slot->second);
      }
      for (std::size_t m = 1; m + 1 < polygon.size(); ++m) {
        cut_triangles.push_back({polygon[0], polygon[m], polygon[m + 1]});
      }
    }
    if (with_front) {
      add_front_pieces(cutter, front, crossing_point, cut_points, cut_triangles, edge_of_point);
      // The blade moving outside the body, or along a piece already drawn, changes nothing.
      std::vector<double> signature;
      signature.reserve(3 * cut_points.size() + 3 * cut_triangles.size());
      for (const Vec3& p : cut_points) {
        signature.insert(signature.end(), {p.x(), p.y(), p.z()});
      }
      for (const Triangle& t : cut_triangles) {
        signature.insert(signature.end(), {static_cast<double>(t[0]), static_cast<double>(t[1]),
                                           static_cast<double>(t[2])});
      }
      if (signature == cut_signature_) {
        return;
      }
      cut_signature_ = std::move(signature);
    }
    // The band past the boundary also keeps the cut's rim off a visual surface that lies on
    // the body's boundary (the body's own surface): corefinement then meets a crossing, not
    // two nearly coplanar triangles.
    if (closed_) {
      add_skirt(cut_points, cut_triangles, edge_of_point);
    }
    visual = cgal_->original;
    cut_surface = to_cgal(cut_points, cut_triangles);
    if (cut_triangles.empty()) {
      corefined = true;
      break;
    }
    // Corefinement asks for surfaces that do not intersect themselves; real visual surfaces
    // sometimes do (SOFA's liver-smooth.obj), and a skirt round a sharp rim may.
    try {
      PMP::corefine(visual, cut_surface);
      corefined = true;
      break;
    } catch (const CGAL::Failure_exception&) {
      front_failures_ += with_front ? 1 : 0;
    }
  }
  if (!corefined) {
    ++failures_;
    return;
  }
  const auto* inside = cgal_->inside.get();

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
  ++revision_;
}

void VisualSurface::add_front_pieces(const XfemCutter& cutter, std::span<const TetId> front,
                                     std::unordered_map<std::uint64_t, VertexId>& crossing_point,
                                     std::vector<Vec3>& cut_points,
                                     std::vector<Triangle>& cut_triangles,
                                     std::vector<std::uint64_t>& edge_of_point) const {
  // Beyond the seed (its future work): the picture opens under the blade before the physics
  // splits. In each tetrahedron the cut has reached but not crossed, the cut so far runs
  // through the crossings of its crossed edges and the blade's line inside it now; both sides'
  // points there lie in the one whole element, so the picture is cut (and shows the cut faces)
  // but stays closed until the physics splits the element and the lips part.
  // The blade's ends in the tetrahedra: on a face (shared by its two tetrahedra) or inside.
  std::map<std::array<VertexId, 3>, VertexId> blade_point;
  constexpr std::uint64_t kNoEdge = ~std::uint64_t{0};
  const BladePose& blade = cutter.last_pose();
  for (TetId t : front) {
    const Tet& tet = rest_mesh_.tet(t);
    const auto x = rest_corners(rest_mesh_, t);
    std::vector<VertexId> points;
    for (const auto& edge : tet_local::kEdges) {
      const auto i = static_cast<std::size_t>(edge[0]);
      const auto j = static_cast<std::size_t>(edge[1]);
      const std::optional<double> along = cutter.crossing(tet[i], tet[j]);
      if (!along) {
        continue;
      }
      const auto [slot, added] = crossing_point.try_emplace(
          edge_key(tet[i], tet[j]), static_cast<VertexId>(cut_points.size()));
      if (added) {
        cut_points.push_back((1.0 - *along) * x[i] + *along * x[j]);
        edge_of_point.push_back(edge_key(tet[i], tet[j]));
      }
      points.push_back(slot->second);
    }
    if (points.size() < 2) {
      continue;  // the cut has not made a piece here yet
    }
    if (const auto clip = clip_segment(x, tet, blade.tip, blade.base)) {
      for (int end = 0; end < 2; ++end) {
        const double s = end == 0 ? clip->enter : clip->exit;
        const int face = end == 0 ? clip->enter_face : clip->exit_face;
        // Keyed by the face it lies on (its vertices, sorted), or, inside, by the tetrahedron
        // and which end it is.
        std::array<VertexId, 3> key{kInvalidId, t, -1 - end};
        if (face >= 0) {
          for (int i = 0, m = 0; i < 4; ++i) {
            if (i != face) {
              key[static_cast<std::size_t>(m++)] = tet[static_cast<std::size_t>(i)];
            }
          }
          std::sort(key.begin(), key.end());
        }
        const auto [slot, added] =
            blade_point.try_emplace(key, static_cast<VertexId>(cut_points.size()));
        if (added) {
          cut_points.push_back(blade.tip + s * (blade.base - blade.tip));
          edge_of_point.push_back(kNoEdge);
        }
        points.push_back(slot->second);
      }
    }
    std::sort(points.begin(), points.end());
    points.erase(std::unique(points.begin(), points.end()), points.end());
    if (points.size() < 3) {
      continue;
    }
    // A convex polygon in the tetrahedron: its corners in order around their centre, in the
    // plane they lie closest to.
    Vec3 centre = Vec3::Zero();
    for (VertexId id : points) {
      centre += cut_points[static_cast<std::size_t>(id)];
    }
    centre /= static_cast<double>(points.size());
    Mat3 spread = Mat3::Zero();
    for (VertexId id : points) {
      const Vec3 d = cut_points[static_cast<std::size_t>(id)] - centre;
      spread += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Mat3> axes(spread);
    const Vec3 u = axes.eigenvectors().col(2);
    const Vec3 v = axes.eigenvectors().col(1);
    const double size = (x[1] - x[0]).norm() + (x[2] - x[0]).norm() + (x[3] - x[0]).norm();
    if (!(axes.eigenvalues()[1] > 1e-12 * size * size)) {
      continue;  // the points lie on a line: no area yet
    }
    // Far from flat: the blade turned, or came back, inside the tetrahedron; no one polygon
    // stands for that cut, and the picture waits for the physics here.
    const Vec3 normal = axes.eigenvectors().col(0);
    const bool flat = std::all_of(points.begin(), points.end(), [&](VertexId id) {
      return std::abs((cut_points[static_cast<std::size_t>(id)] - centre).dot(normal)) <=
             0.02 * size;
    });
    if (!flat) {
      continue;
    }
    std::sort(points.begin(), points.end(), [&](VertexId a, VertexId b) {
      const Vec3 da = cut_points[static_cast<std::size_t>(a)] - centre;
      const Vec3 db = cut_points[static_cast<std::size_t>(b)] - centre;
      return std::atan2(da.dot(v), da.dot(u)) < std::atan2(db.dot(v), db.dot(u));
    });
    for (std::size_t m = 1; m + 1 < points.size(); ++m) {
      cut_triangles.push_back({points[0], points[m], points[m + 1]});
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
    if (last - ends.begin() != 3) {
      continue;
    }
    std::copy(ends.begin(), last, face.begin());
    if (!rest_boundary_.contains(face)) {
      continue;
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
