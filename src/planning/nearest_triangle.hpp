#pragma once
// Closest points on a triangle surface through CGAL's AABB tree (private to planning).

#include <memory>
#include <span>

#include "incise/core/types.hpp"

namespace incise::planning {

class NearestTriangle {
 public:
  NearestTriangle(std::span<const Vec3> points, std::span<const Triangle> triangles);
  ~NearestTriangle();
  NearestTriangle(const NearestTriangle&) = delete;
  NearestTriangle& operator=(const NearestTriangle&) = delete;

  struct Hit {
    Vec3 point;
    int triangle = -1;
  };
  /// The closest point of the surface to `query`, and its triangle. Several threads may ask at
  /// once (the tree is built in the constructor).
  [[nodiscard]] Hit closest(const Vec3& query) const;

 private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
};

}  // namespace incise::planning
