#pragma once
// Rows of values packed in one array (compressed rows), where one row can be rewritten
// without shifting the others: a row that no longer fits its place moves to the end of the
// array, with room to grow further. The model's per-vertex lists after a cut (matrix columns,
// element incidences) change only under the blade, and rebuilding the whole array for them
// was a cost of the body's size. What moved rows leave behind is reclaimed once it reaches a
// quarter of the array (compact_if_fragmented), which gives every row a new place.
//
// Not thread-safe for writing; readers of distinct rows may run in parallel.

#include <algorithm>
#include <cstddef>
#include <span>
#include <vector>

#include "incise/core/growth.hpp"

namespace incise {

/// Rows of values of varying length packed in one array, each with room to grow: an edit
/// rewrites only the rows it touched, and a row that outgrows its place moves to the end.
template <typename T>
class PackedRows {
 public:
  /// Room a moved or new row gets beyond its values: a row under the blade grows a few
  /// values per frame, and would otherwise move at every edit.
  static constexpr std::size_t kRoom = 4;

  /// Packs rows[i] one after another, with no room to spare.
  template <typename Rows>
  void assign(std::size_t count, const Rows& row) {
    begin_.resize(count);
    end_.resize(count);
    room_.resize(count);
    values_.clear();
    for (std::size_t i = 0; i < count; ++i) {
      const auto values = row(i);
      begin_[i] = values_.size();
      values_.insert(values_.end(), values.begin(), values.end());
      end_[i] = values_.size();
      room_[i] = end_[i] - begin_[i];
    }
    live_ = values_.size();
    values_.reserve(capacity_for_moved_rows(live_));
  }

  /// Appends empty rows up to `count`.
  void add_rows(std::size_t count) {
    while (begin_.size() < count) {
      begin_.push_back(values_.size());
      end_.push_back(values_.size());
      room_.push_back(0);
    }
  }

  /// Gives row i these values; true when they differ from what it held. Other rows keep their
  /// places.
  bool set_row(std::size_t i, std::span<const T> values) {
    const std::span<const T> current = row(i);
    if (std::equal(current.begin(), current.end(), values.begin(), values.end())) {
      return false;
    }
    live_ = live_ + values.size() - current.size();
    if (values.size() > room_[i]) {
      const std::size_t begin = values_.size();
      const std::size_t room = values.size() + kRoom;
      if (values_.capacity() < begin + room) {
        values_.reserve(capacity_for_moved_rows(begin + room));  // grow with slack
      }
      values_.resize(begin + room);
      begin_[i] = begin;
      room_[i] = room;
    }
    std::copy(values.begin(), values.end(),
              values_.begin() + static_cast<std::ptrdiff_t>(begin_[i]));
    end_[i] = begin_[i] + values.size();
    return true;
  }

  /// Packs the rows again in order once a quarter of the array is left behind; true when it
  /// did.
  bool compact_if_fragmented() {
    if (4 * (values_.size() - live_) < values_.size()) {
      return false;
    }
    std::vector<T> packed;
    packed.reserve(capacity_for_moved_rows(live_));
    for (std::size_t i = 0; i < begin_.size(); ++i) {
      const std::span<const T> values = row(i);
      begin_[i] = packed.size();
      packed.insert(packed.end(), values.begin(), values.end());
      end_[i] = packed.size();
      room_[i] = values.size();
    }
    values_ = std::move(packed);
    return true;
  }

  /// The number of rows.
  [[nodiscard]] std::size_t rows() const { return begin_.size(); }
  /// Row i's values.
  [[nodiscard]] std::span<const T> row(std::size_t i) const {
    return std::span<const T>(values_).subspan(begin_[i], end_[i] - begin_[i]);
  }
  /// Values in rows (the array minus what moved rows left behind).
  [[nodiscard]] std::size_t live() const { return live_; }
  /// The whole array: row i is storage()[begin()[i] .. end()[i]).
  [[nodiscard]] std::span<const T> storage() const { return values_; }
  /// Each row's first index in storage().
  [[nodiscard]] std::span<const std::size_t> begin() const { return begin_; }
  /// Each row's end in storage().
  [[nodiscard]] std::span<const std::size_t> end() const { return end_; }

 private:
  std::vector<std::size_t> begin_;
  std::vector<std::size_t> end_;
  std::vector<std::size_t> room_;  ///< values the row may hold in place
  std::vector<T> values_;
  std::size_t live_ = 0;
};

}  // namespace incise
