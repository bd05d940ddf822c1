#include "incise/imaging/trilinear.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace incise::imaging {

namespace {

/// SplitMix64: a well-mixed 64-bit hash, for choosing crossings independently of the order.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30U)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27U)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31U);
}

/// Calls visit(edge_id, point) for every crossing on the edges leaving voxels of slices
/// [k_begin, k_end) towards +i, +j and +k.
template <typename Visit>
void for_each_crossing(const VolumeImage& image, double iso, std::size_t k_begin, std::size_t k_end,
                       Visit&& visit) {
  const auto [nx, ny, nz] = image.size;
  const std::array<std::size_t, 3> step{1, nx, nx * ny};
  for (std::size_t k = k_begin; k < k_end; ++k) {
    for (std::size_t j = 0; j < ny; ++j) {
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t here = i + nx * (j + ny * k);
        const double a = image.values[here];
        const std::array<bool, 3> has{i + 1 < nx, j + 1 < ny, k + 1 < nz};
        for (std::size_t axis = 0; axis < 3; ++axis) {
          if (!has[axis]) {
            continue;
          }
          const double b = image.values[here + step[axis]];
          if ((a > iso) == (b > iso)) {
            continue;
          }
          const double t = (iso - a) / (b - a);
          Vec3 p(static_cast<double>(i) * image.spacing.x(),
                 static_cast<double>(j) * image.spacing.y(),
                 static_cast<double>(k) * image.spacing.z());
          p[static_cast<Eigen::Index>(axis)] += t * image.spacing[static_cast<Eigen::Index>(axis)];
          visit(3 * here + axis, p);
        }
      }
    }
  }
}

}  // namespace

TrilinearSample sample_trilinear(const VolumeImage& image, const Vec3& grid_mm) {
  std::array<std::size_t, 3> cell{};
  std::array<double, 3> fraction{};
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const double last = static_cast<double>(image.size[axis] - 1);
    const double index = std::clamp(
        grid_mm[static_cast<Eigen::Index>(axis)] / image.spacing[static_cast<Eigen::Index>(axis)],
        0.0, last);
    const double base = std::min(std::floor(index), std::max(last - 1.0, 0.0));
    cell[axis] = static_cast<std::size_t>(base);
    fraction[axis] = image.size[axis] > 1 ? index - base : 0.0;
  }
  auto at = [&](std::size_t di, std::size_t dj, std::size_t dk) -> double {
    const std::size_t i = std::min(cell[0] + di, image.size[0] - 1);
    const std::size_t j = std::min(cell[1] + dj, image.size[1] - 1);
    const std::size_t k = std::min(cell[2] + dk, image.size[2] - 1);
    return image.at(i, j, k);
  };
  const double c000 = at(0, 0, 0);
  const double c100 = at(1, 0, 0);
  const double c010 = at(0, 1, 0);
  const double c110 = at(1, 1, 0);
  const double c001 = at(0, 0, 1);
  const double c101 = at(1, 0, 1);
  const double c011 = at(0, 1, 1);
  const double c111 = at(1, 1, 1);
  const auto [x, y, z] = fraction;
  const double c00 = c000 + x * (c100 - c000);
  const double c10 = c010 + x * (c110 - c010);
  const double c01 = c001 + x * (c101 - c001);
  const double c11 = c011 + x * (c111 - c011);
  const double c0 = c00 + y * (c10 - c00);
  const double c1 = c01 + y * (c11 - c01);
  TrilinearSample sample;
  sample.value = c0 + z * (c1 - c0);
  const double dx = (1 - y) * (1 - z) * (c100 - c000) + y * (1 - z) * (c110 - c010) +
                    (1 - y) * z * (c101 - c001) + y * z * (c111 - c011);
  const double dy = (1 - z) * (c10 - c00) + z * (c11 - c01);
  const double dz = c1 - c0;
  sample.gradient = Vec3(dx / image.spacing.x(), dy / image.spacing.y(), dz / image.spacing.z());
  return sample;
}

bool project_to_isosurface(const VolumeImage& image, double iso, Vec3& grid_mm, int iterations) {
  const double settled = 1e-3 * image.spacing.minCoeff();  // mm
  for (int n = 0; n < iterations; ++n) {
    const TrilinearSample s = sample_trilinear(image, grid_mm);
    const double squared = s.gradient.squaredNorm();
    if (!(squared > 0.0)) {
      return false;
    }
    if (std::abs(s.value - iso) < settled * std::sqrt(squared)) {
      return true;  // first-order distance left below the tolerance
    }
    const Vec3 step = ((s.value - iso) / squared) * s.gradient;
    // No step longer than a voxel: the cell's gradient says nothing farther away.
    const double length = step.norm();
    const double longest = image.spacing.maxCoeff();
    grid_mm -= length > longest ? (longest / length) * step : step;
  }
  return false;
}

std::vector<std::uint8_t> outside_of(const VolumeImage& image, double iso) {
  // Runs of voxels at most iso along i, joined (union-find) with the runs they overlap in the
  // rows beside them (j - 1 and k - 1): the regions are unions of runs. A flood fill voxel by
  // voxel took 3.7-4.6 s on a 512 x 512 x 300 CT (random access over 78M voxels, one
  // thread); runs are found slice by slice in parallel, and a head has a few per row.
  // (not a structured binding: clang 14 cannot capture those in the lambdas below)
  const std::size_t nx = image.size[0];
  const std::size_t ny = image.size[1];
  const std::size_t nz = image.size[2];
  struct Run {
    std::uint32_t begin = 0;  // i of the first voxel
    std::uint32_t end = 0;    // one past the last
  };
  std::vector<std::vector<Run>> slice_runs(nz);
  std::vector<std::vector<std::size_t>> slice_rows(nz);  // per slice: each row's first run
  tbb::parallel_for(std::size_t{0}, nz, [&](std::size_t k) {
    std::vector<Run>& runs = slice_runs[k];
    std::vector<std::size_t>& rows = slice_rows[k];
    rows.reserve(ny + 1);
    for (std::size_t j = 0; j < ny; ++j) {
      rows.push_back(runs.size());
      const float* row = &image.values[nx * (j + ny * k)];
      std::size_t i = 0;
      while (i < nx) {
        while (i < nx && row[i] > iso) {
          ++i;
        }
        if (i == nx) {
          break;
        }
        const std::size_t begin = i;
        while (i < nx && !(row[i] > iso)) {
          ++i;
        }
        runs.push_back({static_cast<std::uint32_t>(begin), static_cast<std::uint32_t>(i)});
      }
    }
    rows.push_back(runs.size());
  });
  std::vector<std::size_t> first_of_slice(nz + 1, 0);
  for (std::size_t k = 0; k < nz; ++k) {
    first_of_slice[k + 1] = first_of_slice[k] + slice_runs[k].size();
  }
  std::vector<std::size_t> parent(first_of_slice[nz]);
  for (std::size_t r = 0; r < parent.size(); ++r) {
    parent[r] = r;
  }
  auto find = [&](std::size_t r) {
    while (parent[r] != r) {
      parent[r] = parent[parent[r]];
      r = parent[r];
    }
    return r;
  };
  // Joins the overlapping runs of two rows (first ids a0, b0; both sorted along i).
  auto join_rows = [&](const std::vector<Run>& a_runs, std::size_t a_begin, std::size_t a_end,
                       std::size_t a0, const std::vector<Run>& b_runs, std::size_t b_begin,
                       std::size_t b_end, std::size_t b0) {
    std::size_t x = a_begin;
    std::size_t y = b_begin;
    while (x < a_end && y < b_end) {
      const Run& ra = a_runs[x];
      const Run& rb = b_runs[y];
      if (ra.begin < rb.end && rb.begin < ra.end) {
        const std::size_t root_a = find(a0 + x);
        const std::size_t root_b = find(b0 + y);
        if (root_a != root_b) {
          parent[std::max(root_a, root_b)] = std::min(root_a, root_b);
        }
      }
      if (ra.end < rb.end) {
        ++x;
      } else {
        ++y;
      }
    }
  };
  for (std::size_t k = 0; k < nz; ++k) {
    const std::vector<std::size_t>& rows = slice_rows[k];
    for (std::size_t j = 0; j < ny; ++j) {
      if (j > 0) {
        join_rows(slice_runs[k], rows[j], rows[j + 1], first_of_slice[k], slice_runs[k],
                  rows[j - 1], rows[j], first_of_slice[k]);
      }
      if (k > 0) {
        const std::vector<std::size_t>& below = slice_rows[k - 1];
        join_rows(slice_runs[k], rows[j], rows[j + 1], first_of_slice[k], slice_runs[k - 1],
                  below[j], below[j + 1], first_of_slice[k - 1]);
      }
    }
  }
  // A region is outside when one of its runs touches the scan's border.
  std::vector<std::uint8_t> root_outside(parent.size(), 0);
  for (std::size_t k = 0; k < nz; ++k) {
    for (std::size_t j = 0; j < ny; ++j) {
      const bool border_row = j == 0 || k == 0 || j + 1 == ny || k + 1 == nz;
      for (std::size_t r = slice_rows[k][j]; r < slice_rows[k][j + 1]; ++r) {
        const Run& run = slice_runs[k][r];
        if (border_row || run.begin == 0 || run.end == nx) {
          root_outside[find(first_of_slice[k] + r)] = 1;
        }
      }
    }
  }
  for (std::size_t r = 0; r < parent.size(); ++r) {
    parent[r] = find(r);  // flat, so the parallel fill below only reads
  }
  std::vector<std::uint8_t> outside(image.values.size(), 0);
  tbb::parallel_for(std::size_t{0}, nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j) {
      for (std::size_t r = slice_rows[k][j]; r < slice_rows[k][j + 1]; ++r) {
        if (root_outside[parent[first_of_slice[k] + r]] != 0) {
          const Run& run = slice_runs[k][r];
          std::fill_n(outside.begin() + static_cast<std::ptrdiff_t>(nx * (j + ny * k) + run.begin),
                      run.end - run.begin, std::uint8_t{1});
        }
      }
    }
  });
  return outside;
}

IsoCrossings iso_crossings(const VolumeImage& image, double iso, std::size_t wanted,
                           std::uint64_t seed, const std::vector<std::uint8_t>* outside) {
  IsoCrossings result;
  const std::size_t nz = image.size[2];
  result.total = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, nz), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t count) {
        for_each_crossing(image, iso, r.begin(), r.end(),
                          [&](std::uint64_t, const Vec3&) { ++count; });
        return count;
      },
      [](std::size_t a, std::size_t b) { return a + b; });
  if (result.total == 0) {
    return result;
  }
  // Keep an edge when its hash falls below the wanted fraction of the hash range.
  const double fraction =
      std::min(1.0, static_cast<double>(wanted) / static_cast<double>(result.total));
  const auto threshold =
      fraction >= 1.0
          ? std::numeric_limits<std::uint64_t>::max()
          : static_cast<std::uint64_t>(
                fraction * static_cast<double>(std::numeric_limits<std::uint64_t>::max()));
  // The edge's voxel at most iso: the crossing's own (edge / 3) or its neighbour along the axis.
  const std::array<std::size_t, 3> step{1, image.size[0], image.size[0] * image.size[1]};
  auto low_voxel = [&](std::uint64_t edge) {
    const auto here = static_cast<std::size_t>(edge / 3);
    return image.values[here] > iso ? here + step[static_cast<std::size_t>(edge % 3)] : here;
  };
  using Found = std::pair<std::vector<Vec3>, std::vector<std::uint8_t>>;
  Found found = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, nz), Found{},
      [&](const tbb::blocked_range<std::size_t>& r, Found part) {
        for_each_crossing(image, iso, r.begin(), r.end(), [&](std::uint64_t edge, const Vec3& p) {
          if (mix(edge ^ mix(seed)) <= threshold) {
            part.first.push_back(p);
            if (outside != nullptr) {
              part.second.push_back((*outside)[low_voxel(edge)] == 0 ? 1 : 0);
            }
          }
        });
        return part;
      },
      [](Found a, Found b) {
        a.first.insert(a.first.end(), b.first.begin(), b.first.end());
        a.second.insert(a.second.end(), b.second.begin(), b.second.end());
        return a;
      });
  result.points = std::move(found.first);
  result.enclosed = std::move(found.second);
  return result;
}

}  // namespace incise::imaging
