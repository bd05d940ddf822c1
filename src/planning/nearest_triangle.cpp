#include "nearest_triangle.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <vector>

namespace incise::planning {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Triangle3 = Kernel::Triangle_3;
using Iterator = std::vector<Triangle3>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
using AabbTree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

Kernel::Point_3 to_point(const Vec3& p) {
  return {p.x(), p.y(), p.z()};
}
}  // namespace

struct NearestTriangle::Tree {
  std::vector<Triangle3> triangles;
  AabbTree tree;
};

NearestTriangle::NearestTriangle(std::span<const Vec3> points, std::span<const Triangle> triangles)
    : tree_(std::make_unique<Tree>()) {
  tree_->triangles.reserve(triangles.size());
  for (const Triangle& t : triangles) {
    tree_->triangles.emplace_back(to_point(points[static_cast<std::size_t>(t[0])]),
                                  to_point(points[static_cast<std::size_t>(t[1])]),
                                  to_point(points[static_cast<std::size_t>(t[2])]));
  }
  tree_->tree.insert(tree_->triangles.cbegin(), tree_->triangles.cend());
  tree_->tree.build();  // built now: concurrent queries only read it
  tree_->tree.accelerate_distance_queries();
}

NearestTriangle::~NearestTriangle() = default;

NearestTriangle::Hit NearestTriangle::closest(const Vec3& query) const {
  const auto [point, primitive] = tree_->tree.closest_point_and_primitive(to_point(query));
  Hit hit;
  hit.point = Vec3(point.x(), point.y(), point.z());
  hit.triangle = static_cast<int>(primitive - tree_->triangles.cbegin());
  return hit;
}

}  // namespace incise::planning
