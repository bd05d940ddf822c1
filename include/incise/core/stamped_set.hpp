#pragma once
// A set of small non-negative ids (tetrahedra, vertices) emptied in constant time: a stamp per
// id, the set's members being those stamped with the current one. Walks over thousands of
// tetrahedra each pose test membership without hashing or clearing.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace incise {

/// Ids 0..n-1 in or out; emptied by a new stamp, not by a pass over the ids.
class StampedSet {
 public:
  /// Empties the set and makes room for ids below `ids`.
  void clear(std::size_t ids) {
    if (stamps_.size() < ids) {
      stamps_.resize(ids + ids / 2 + 16, 0);
    }
    if (++stamp_ == 0) {  // wrapped: old stamps could match again
      std::fill(stamps_.begin(), stamps_.end(), 0);
      stamp_ = 1;
    }
  }
  /// Whether `id` is in the set (below the size given to clear()).
  [[nodiscard]] bool contains(std::int64_t id) const {
    return stamps_[static_cast<std::size_t>(id)] == stamp_;
  }
  /// Puts `id` in; false if it was in already.
  bool insert(std::int64_t id) {
    std::uint32_t& stamp = stamps_[static_cast<std::size_t>(id)];
    if (stamp == stamp_) {
      return false;
    }
    stamp = stamp_;
    return true;
  }

 private:
  std::vector<std::uint32_t> stamps_;
  std::uint32_t stamp_ = 0;
};

}  // namespace incise
