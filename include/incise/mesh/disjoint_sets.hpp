#pragma once
// Disjoint sets over vertex ids (union-find with path halving): pieces of a mesh joined
// through shared corners, for the subdivision cutter's meshes and XFEM's virtual meshes alike.

#include <numeric>
#include <vector>

#include "incise/core/types.hpp"

namespace incise {

/// Union-find over vertex ids 0..size-1, with path halving.
class DisjointSets {
 public:
  /// Every id in a set of its own.
  explicit DisjointSets(std::size_t size) : parent_(size) {
    std::iota(parent_.begin(), parent_.end(), VertexId{0});
  }
  /// The representative of v's set.
  [[nodiscard]] VertexId find(VertexId v) {
    while (parent_[static_cast<std::size_t>(v)] != v) {
      parent_[static_cast<std::size_t>(v)] =
          parent_[static_cast<std::size_t>(parent_[static_cast<std::size_t>(v)])];
      v = parent_[static_cast<std::size_t>(v)];
    }
    return v;
  }
  /// Joins the sets of a and b.
  void join(VertexId a, VertexId b) { parent_[static_cast<std::size_t>(find(a))] = find(b); }

 private:
  std::vector<VertexId> parent_;
};

}  // namespace incise
