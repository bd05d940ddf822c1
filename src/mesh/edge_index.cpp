#include "incise/mesh/edge_index.hpp"

#include <algorithm>
#include <bit>

#include "incise/core/error.hpp"

namespace incise {

std::size_t EdgeIndex::home(std::uint64_t key) const {
  // Fibonacci hashing: edge keys are structured (two vertex ids side by side), so they are
  // mixed by a multiply and the top bits taken.
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift_);
}

std::size_t EdgeIndex::probe(std::uint64_t key) const {
  const std::size_t mask = slots_.size() - 1;
  std::size_t at = home(key);
  while (slots_[at].key != kEmpty && slots_[at].key != key) {
    at = (at + 1) & mask;
  }
  return at;
}

EdgeId EdgeIndex::find(std::uint64_t key) const {
  if (slots_.empty()) {
    return kInvalidId;
  }
  const Slot& slot = slots_[probe(key)];
  return slot.key == key ? slot.id : kInvalidId;
}

EdgeIndex::Slot& EdgeIndex::slot_for(std::uint64_t key) {
  INCISE_ASSERT(key != kEmpty, "an edge key with its top bit set");
  if (4 * (size_ + 1) > 3 * slots_.size()) {
    grow_to(std::max<std::size_t>(16, 2 * slots_.size()));
  }
  return slots_[probe(key)];
}

std::pair<EdgeId, bool> EdgeIndex::try_emplace(std::uint64_t key, EdgeId id) {
  Slot& slot = slot_for(key);
  if (slot.key == key) {
    return {slot.id, false};
  }
  slot = {key, id};
  ++size_;
  return {id, true};
}

void EdgeIndex::assign(std::uint64_t key, EdgeId id) {
  Slot& slot = slot_for(key);
  if (slot.key != key) {
    slot.key = key;
    ++size_;
  }
  slot.id = id;
}

bool EdgeIndex::erase(std::uint64_t key) {
  if (slots_.empty()) {
    return false;
  }
  const std::size_t mask = slots_.size() - 1;
  std::size_t hole = probe(key);
  if (slots_[hole].key != key) {
    return false;
  }
  // Backward-shift deletion: move later entries of the run into the hole when their home slot
  // does not lie (cyclically) between the hole and them, so every key stays reachable from its
  // home without tombstones.
  for (std::size_t next = (hole + 1) & mask; slots_[next].key != kEmpty; next = (next + 1) & mask) {
    const std::size_t want = home(slots_[next].key);
    const bool reachable_without = ((next - want) & mask) < ((next - hole) & mask);
    if (!reachable_without) {
      slots_[hole] = slots_[next];
      hole = next;
    }
  }
  slots_[hole] = Slot{};
  --size_;
  return true;
}

void EdgeIndex::clear() {
  std::fill(slots_.begin(), slots_.end(), Slot{});
  size_ = 0;
}

void EdgeIndex::reserve(std::size_t count) {
  const std::size_t needed = std::bit_ceil(std::max<std::size_t>(16, (4 * count + 2) / 3));
  if (needed > slots_.size()) {
    grow_to(needed);
  }
}

void EdgeIndex::grow_to(std::size_t slots) {
  std::vector<Slot> old = std::exchange(slots_, std::vector<Slot>(slots));
  shift_ = 64 - std::countr_zero(slots);
  for (const Slot& slot : old) {
    if (slot.key != kEmpty) {
      slots_[probe(slot.key)] = slot;
    }
  }
}

}  // namespace incise
