#pragma once
// The mesh's edge lookup: an edge's id from its two vertices (edge_key). Every tetrahedron a cut
// attaches looks up its six edges, several thousand lookups per cutting frame at 384k
// tetrahedra. std::unordered_map chains its entries in separate nodes, so a lookup in a table
// that no longer fits in cache costs three misses (bucket, the node before, the node), and that
// made the index a third of the subdivision cutter's time at 384k tetrahedra (BENCHMARKS.md).
// This table keeps key and id together in one flat array probed linearly: one miss. The
// standard library has no open-addressing map and the project's dependencies none either, so
// it is written here; it holds only what the mesh needs (no iteration, no generic types).

#include <cstdint>
#include <utility>
#include <vector>

#include "incise/core/types.hpp"

namespace incise {

/// Edge key (two vertex ids side by side) to edge id: a flat table probed linearly from a
/// Fibonacci hash, at most 3/4 full, erased by backward shift (no tombstones).
class EdgeIndex {
 public:
  EdgeIndex() = default;
  EdgeIndex(const EdgeIndex&) = default;             ///< a copy of the table
  EdgeIndex& operator=(const EdgeIndex&) = default;  ///< a copy of the table
  /// The moved-from index is empty.
  EdgeIndex(EdgeIndex&& other) noexcept { *this = std::move(other); }
  /// Takes the other's table; the moved-from index is empty.
  EdgeIndex& operator=(EdgeIndex&& other) noexcept {
    if (this == &other) {
      return *this;
    }
    slots_ = std::move(other.slots_);
    size_ = std::exchange(other.size_, 0);
    shift_ = std::exchange(other.shift_, 64);
    other.slots_.clear();
    return *this;
  }
  ~EdgeIndex() = default;

  /// The id stored for `key`, or kInvalidId.
  [[nodiscard]] EdgeId find(std::uint64_t key) const;
  /// Stores `id` for `key` unless the key is there; returns the stored id and whether it was new.
  std::pair<EdgeId, bool> try_emplace(std::uint64_t key, EdgeId id);
  /// Stores `id` for `key`, replacing any id there.
  void assign(std::uint64_t key, EdgeId id);
  /// Removes `key`; false if it was not there.
  bool erase(std::uint64_t key);
  void clear();  ///< removes every key, keeping the table's room
  /// Room for `count` keys without growing.
  void reserve(std::size_t count);
  [[nodiscard]] std::size_t size() const { return size_; }  ///< keys stored

 private:
  /// No edge key has its top bit set (vertex ids are non-negative 32-bit numbers).
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  struct Slot {
    std::uint64_t key = kEmpty;
    EdgeId id = kInvalidId;
  };
  [[nodiscard]] std::size_t home(std::uint64_t key) const;
  /// The slot holding `key`, or the empty slot where it would go.
  [[nodiscard]] std::size_t probe(std::uint64_t key) const;
  /// probe()'s slot, after growing the table if one more key would make it over 3/4 full.
  [[nodiscard]] Slot& slot_for(std::uint64_t key);
  void grow_to(std::size_t slots);

  std::vector<Slot> slots_;  ///< a power of two in size, at most 3/4 full
  std::size_t size_ = 0;
  int shift_ = 64;  ///< 64 - log2(slots): the hash's top bits pick the home slot
};

}  // namespace incise
