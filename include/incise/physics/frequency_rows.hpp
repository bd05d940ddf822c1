#pragma once
// The rows of a Gershgorin bound on a body's squared frequencies (1/s^2, one row per vertex)
// and their largest, kept under mesh edits: a model sets again the rows an edit changed, and
// the largest is searched for over every row only when the row that held it shrank. Explicit
// schemes ask for the bound every step; whole-body passes are left to construction and
// restores.

#include <cstddef>
#include <functional>
#include <vector>

#include "incise/core/types.hpp"

namespace incise {

/// Per-vertex bounds on a body's highest natural frequency (rad/s, Gershgorin rows) and their
/// largest, kept row by row as edits change some of them.
class FrequencyRows {
 public:
  /// Every row afresh (in parallel: each row is a function of the body alone).
  void fill(std::size_t rows, const std::function<double(VertexId)>& row);
  /// New rows up to `rows`, each 0 until set.
  void grow(std::size_t rows) { rows_.resize(rows, 0.0); }
  /// A vertex's row (rad/s), after an edit changed it.
  void set(VertexId vertex, double row);
  /// After the rows an edit changed were set: the largest again where it may have shrunk.
  void settle();
  /// Whether no row was filled yet.
  [[nodiscard]] bool empty() const { return rows_.empty(); }
  /// The largest row (rad/s).
  [[nodiscard]] double largest() const { return largest_; }

 private:
  std::vector<double> rows_;
  double largest_ = 0.0;
  bool lost_largest_ = false;
};

}  // namespace incise
