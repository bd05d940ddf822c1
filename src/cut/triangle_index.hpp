#pragma once
// Triangles in a hierarchical spatial hash: each triangle is filed at the level whose cell
// size matches its own size, so a query looks at the triangles near it whether they are few
// and large or many and small (a fixed cell size made a query near thousands of small
// triangles scan all of them). Internal to the cut module.

#include <array>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "incise/core/state_archive.hpp"
#include "incise/core/types.hpp"

namespace incise::detail {

class TriangleIndex {
 public:
  /// `finest` (m): the smallest cell size used; larger triangles go to levels of twice, four
  /// times... that size.
  explicit TriangleIndex(double finest = 1.0) : finest_(finest) {}
  void set_finest_cell(double finest) { finest_ = finest; }

  /// Adds a triangle, visible to queries only inside the box [low, high] (m), with a tag the
  /// caller chooses (the cutter's sweep number).
  void add(const std::array<Vec3, 3>& triangle,
           const Vec3& low = Vec3::Constant(-std::numeric_limits<double>::max()),
           const Vec3& high = Vec3::Constant(std::numeric_limits<double>::max()),
           std::int64_t tag = 0);
  [[nodiscard]] std::size_t size() const { return triangles_.size(); }
  [[nodiscard]] const std::array<Vec3, 3>& triangle(std::size_t index) const {
    return triangles_[index].corners;
  }
  [[nodiscard]] std::int64_t tag(std::size_t index) const { return triangles_[index].tag; }
  /// The triangles and their boxes; loading files them again in the same order.
  void save_state(StateWriter& out) const;
  void load_state(StateReader& in);

  /// The stored triangle nearest to `point` among those within `radius` (m), or -1; its
  /// distance in `distance`.
  [[nodiscard]] std::int64_t nearest(const Vec3& point, double radius, double* distance) const;
  /// Whether a stored triangle lies within `radius` (m) of `point`.
  [[nodiscard]] bool any_within(const Vec3& point, double radius) const;
  /// The tags in [first, last] of the stored triangles within `radius` (m) of `point`, sorted,
  /// each once (triangles with other tags are not even measured).
  [[nodiscard]] std::vector<std::int64_t> tags_within(
      const Vec3& point, double radius,
      std::int64_t first = std::numeric_limits<std::int64_t>::min(),
      std::int64_t last = std::numeric_limits<std::int64_t>::max()) const;

 private:
  struct Stored {
    std::array<Vec3, 3> corners;
    Vec3 low;  ///< where it is valid (m)
    Vec3 high;
    std::int64_t tag = 0;
  };
  using Cell = Eigen::Array<long, 3, 1>;
  [[nodiscard]] static std::uint64_t key(int level, const Cell& cell);
  [[nodiscard]] double cell_size(int level) const;
  /// Calls visit(index, squared distance) for stored triangles within `radius`, nearer cells
  /// first; visit returns the squared radius still of interest (only triangles at most that
  /// far are visited from then on), or a negative number to stop.
  /// `accept(index)`, when given, filters triangles before their distance is measured.
  template <typename Visit, typename Accept>
  void within(const Vec3& point, double radius, Visit visit, Accept accept) const;
  template <typename Visit>
  void within(const Vec3& point, double radius, Visit visit) const {
    within(point, radius, visit, [](std::uint32_t) { return true; });
  }

  static constexpr int kLevels = 24;  ///< the coarsest cell is 2^23 times the finest

  double finest_;
  std::vector<Stored> triangles_;
  /// Triangles too far out or too large to file in cells (see kFarthestCell in the source),
  /// measured by every query.
  std::vector<std::uint32_t> aside_;
  std::vector<int> levels_;  ///< levels holding at least one triangle
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> cells_;
  /// Per level, the cells holding triangles: a query whose box spans more cells than a level
  /// holds scans these instead of the box (a wide query among thousands of tiny cut
  /// triangles looked up hundreds of thousands of empty cells).
  std::array<std::vector<Cell>, kLevels> occupied_;
};

}  // namespace incise::detail
