#include "triangle_index.hpp"

#include <algorithm>
#include <cmath>

#include "incise/core/clamped_floor.hpp"
#include "incise/mesh/predicates.hpp"

namespace incise::detail {

namespace {

/// Cells farther than this from the origin, in cells of their level, are not filed: no body
/// lies 2^40 of the finest cells away (10^7 km at a 10 um cell), and the cell number of a
/// coordinate much beyond would not fit a long. A triangle reaching there (a blade pose far
/// off in a path, or a corrupt checkpoint) is kept aside and measured by every query.
constexpr double kFarthestCell = 0x1p40;
/// Cells a triangle may be filed in; a larger one is kept aside too (see above).
constexpr double kMaxBoxCells = 4096.0;

/// floor(x / size), saturated at +-kFarthestCell (NaN: the far negative end).
long cell_number(double x, double size) {
  constexpr auto kFarthest = static_cast<long>(kFarthestCell);
  return clamped_floor(x / size, -kFarthest, kFarthest);
}

Eigen::Array<long, 3, 1> cell_of(const Vec3& point, double size) {
  return {cell_number(point[0], size), cell_number(point[1], size), cell_number(point[2], size)};
}

}  // namespace

double TriangleIndex::cell_size(int level) const {
  return std::ldexp(finest_, level);
}

std::uint64_t TriangleIndex::key(int level, const Cell& cell) {
  // 19 bits per axis, offset so negative cells hash too, and the level in the top bits.
  const auto part = [](long value) {
    return static_cast<std::uint64_t>(value + (1L << 18)) & 0x7ffffU;
  };
  return static_cast<std::uint64_t>(level) << 57U | part(cell[0]) << 38U | part(cell[1]) << 19U |
         part(cell[2]);
}

void TriangleIndex::add(const std::array<Vec3, 3>& t, const Vec3& box_low, const Vec3& box_high,
                        std::int64_t tag) {
  const Vec3 low = t[0].cwiseMin(t[1]).cwiseMin(t[2]).cwiseMax(box_low);
  const Vec3 high = t[0].cwiseMax(t[1]).cwiseMax(t[2]).cwiseMin(box_high);
  if ((low.array() > high.array()).any()) {
    return;
  }
  // Degenerate triangles (a blade that did not move) add nothing the neighbouring moves'
  // triangles do not already hold, and only slow queries down.
  const double longest2 = std::max(
      {(t[1] - t[0]).squaredNorm(), (t[2] - t[1]).squaredNorm(), (t[0] - t[2]).squaredNorm()});
  const double area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
  if (!(area > 1e-12 * longest2)) {
    return;
  }
  // Cells about as large as the triangle is wide, but few enough per triangle: a long thin
  // swept triangle (a blade across the whole body, moved a little) is filed in the cells along
  // it, not in one cell as large as its box, where every query nearby would test it.
  const double width = 2.0 * area / std::sqrt(longest2);
  const double wanted = std::max(width, std::sqrt(area / 16.0));
  const Vec3 extent = high - low;
  int level = 0;
  while (level + 1 < kLevels && cell_size(level) < wanted) {
    ++level;
  }
  const auto box_cells = [&](int at) {
    return ((extent.array() / cell_size(at)).floor() + 1.0).prod();
  };
  while (level + 1 < kLevels && box_cells(level) > kMaxBoxCells) {
    ++level;
  }
  if (std::find(levels_.begin(), levels_.end(), level) == levels_.end()) {
    levels_.push_back(level);
  }
  const auto index = static_cast<std::uint32_t>(triangles_.size());
  triangles_.push_back({t, box_low, box_high, tag});
  const double size = cell_size(level);
  const double farthest = kFarthestCell * size;
  if (!((low.array().abs() < farthest).all() && (high.array().abs() < farthest).all()) ||
      box_cells(level) > kMaxBoxCells) {
    aside_.push_back(index);
    return;
  }
  // A cell meets the triangle only if its centre is within half its diagonal of it.
  const double reach2 = 0.75 * size * size * (1.0 + 1e-9);
  const Cell first = cell_of(low, size);
  const Cell last = cell_of(high, size);
  for (long k = first[2]; k <= last[2]; ++k) {
    for (long j = first[1]; j <= last[1]; ++j) {
      for (long i = first[0]; i <= last[0]; ++i) {
        const Vec3 centre = (Vec3(double(i), double(j), double(k)).array() + 0.5) * size;
        if (squared_distance_to_triangle(centre, t[0], t[1], t[2]) <= reach2) {
          auto& cell = cells_[key(level, Cell(i, j, k))];
          if (cell.empty()) {
            occupied_[static_cast<std::size_t>(level)].push_back(Cell(i, j, k));
          }
          cell.push_back(index);
        }
      }
    }
  }
}

template <typename Visit, typename Accept>
void TriangleIndex::within(const Vec3& point, double radius, Visit visit, Accept accept) const {
  // Cells in shells of growing distance around the point's cell, so a nearest-triangle query
  // among thousands of thin swept strips (a finely sampled path) stops once the shells lie
  // farther than the nearest triangle found: the box of the whole radius held up to a million
  // cells at the finest level.
  double radius2 = radius * radius;
  // One stored triangle: measured, and visited if within the radius still of interest; true
  // when the visit asks to stop.
  const auto try_triangle = [&](std::uint32_t index) {
    if (!accept(index)) {
      return false;
    }
    const Stored& stored = triangles_[index];
    const double reach = std::sqrt(radius2);
    if ((point.array() < stored.low.array() - reach).any() ||
        (point.array() > stored.high.array() + reach).any()) {
      return false;
    }
    const double d2 = squared_distance_to_triangle(point, stored.corners[0], stored.corners[1],
                                                   stored.corners[2]);
    if (d2 <= radius2) {
      const double next = visit(index, d2);
      if (next < 0.0) {
        return true;
      }
      radius2 = std::min(radius2, next);
    }
    return false;
  };
  for (const std::uint32_t index : aside_) {
    if (try_triangle(index)) {
      return;
    }
  }
  for (int level : levels_) {
    const double size = cell_size(level);
    const Cell centre = cell_of(point, size);
    const Cell first = cell_of(point.array() - radius, size);
    const Cell last = cell_of(point.array() + radius, size);
    const long shells = std::max({centre[0] - first[0], last[0] - centre[0], centre[1] - first[1],
                                  last[1] - centre[1], centre[2] - first[2], last[2] - centre[2]});
    const auto visit_cell = [&](long i, long j, long k) {
      if (i < first[0] || i > last[0] || j < first[1] || j > last[1] || k < first[2] ||
          k > last[2]) {
        return false;
      }
      const auto it = cells_.find(key(level, Cell(i, j, k)));
      if (it == cells_.end()) {
        return false;
      }
      for (std::uint32_t index : it->second) {
        if (try_triangle(index)) {
          return true;
        }
      }
      return false;
    };
    const std::vector<Cell>& occupied = occupied_[static_cast<std::size_t>(level)];
    const double box_cells = ((last - first).cast<double>() + 1.0).prod();
    if (box_cells > static_cast<double>(occupied.size())) {
      // Fewer occupied cells than cells in the box: visit those, nearest first.
      std::vector<std::pair<double, std::size_t>> order;
      for (std::size_t c = 0; c < occupied.size(); ++c) {
        const Cell& cell = occupied[c];
        if ((cell < first).any() || (cell > last).any()) {
          continue;
        }
        const Vec3 low = cell.cast<double>().matrix() * size;
        const Vec3 gap = (low - point).cwiseMax(point - low - Vec3::Constant(size)).cwiseMax(0.0);
        order.emplace_back(gap.squaredNorm(), c);
      }
      std::sort(order.begin(), order.end());
      for (const auto& [gap2, c] : order) {
        if (gap2 > radius2) {
          break;
        }
        const Cell& cell = occupied[c];
        if (visit_cell(cell[0], cell[1], cell[2])) {
          return;
        }
      }
      continue;
    }
    for (long shell = 0; shell <= shells; ++shell) {
      // Every point of a cell in this shell is at least (shell - 1) cells away.
      const double gap = static_cast<double>(shell - 1) * size;
      if (gap > 0.0 && gap * gap > radius2) {
        break;
      }
      for (long k = -shell; k <= shell; ++k) {
        for (long j = -shell; j <= shell; ++j) {
          const bool face = std::abs(k) == shell || std::abs(j) == shell;
          const long step = face || shell == 0 ? 1 : 2 * shell;
          for (long i = -shell; i <= shell; i += step) {
            if (visit_cell(centre[0] + i, centre[1] + j, centre[2] + k)) {
              return;
            }
          }
        }
      }
    }
  }
}

std::int64_t TriangleIndex::nearest(const Vec3& point, double radius, double* distance) const {
  std::int64_t best = -1;
  double best2 = std::numeric_limits<double>::infinity();
  within(point, radius, [&](std::uint32_t index, double d2) {
    if (d2 < best2 || (d2 == best2 && static_cast<std::int64_t>(index) < best)) {
      best2 = d2;
      best = index;
    }
    return best2;  // only nearer triangles matter from here on
  });
  if (distance != nullptr) {
    *distance = std::sqrt(best2);
  }
  return best;
}

bool TriangleIndex::any_within(const Vec3& point, double radius) const {
  bool found = false;
  within(point, radius, [&](std::uint32_t, double) {
    found = true;
    return -1.0;
  });
  return found;
}

std::vector<std::int64_t> TriangleIndex::tags_within(const Vec3& point, double radius,
                                                     std::int64_t first, std::int64_t last) const {
  std::vector<std::int64_t> tags;
  const double radius2 = radius * radius;
  within(
      point, radius,
      [&](std::uint32_t index, double) {
        tags.push_back(triangles_[index].tag);
        return radius2;  // every triangle within the radius
      },
      [&](std::uint32_t index) {
        const std::int64_t tag = triangles_[index].tag;
        return tag >= first && tag <= last;
      });
  std::sort(tags.begin(), tags.end());
  tags.erase(std::unique(tags.begin(), tags.end()), tags.end());
  return tags;
}

void TriangleIndex::save_state(StateWriter& out) const {
  out.tag("swept triangles");
  out.value(finest_);
  out.values(triangles_);
}

void TriangleIndex::load_state(StateReader& in) {
  in.tag("swept triangles");
  finest_ = in.value<double>("finest cell");
  if (!(finest_ > 0.0) || !std::isfinite(finest_)) {
    in.fail("finest cell", "is not a positive length");
  }
  const std::vector<Stored> stored = in.values<Stored>("swept triangles");
  triangles_.clear();
  aside_.clear();
  levels_.clear();
  cells_.clear();
  for (auto& cells : occupied_) {
    cells.clear();
  }
  for (const Stored& s : stored) {
    add(s.corners, s.low, s.high, s.tag);
  }
  if (triangles_.size() != stored.size()) {
    in.fail("swept triangles", "a stored triangle was not accepted again");
  }
}

}  // namespace incise::detail
