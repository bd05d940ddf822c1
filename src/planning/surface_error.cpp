#include "incise/planning/surface_error.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>

#include "incise/imaging/trilinear.hpp"
#include "incise/mesh/disjoint_sets.hpp"
#include "nearest_triangle.hpp"

namespace incise::planning {

namespace {

OneSidedDistance summarize(std::vector<double> distances) {
  OneSidedDistance result;
  result.samples = distances.size();
  if (distances.empty()) {
    return result;
  }
  std::sort(distances.begin(), distances.end());
  result.max = distances.back();
  result.p99 =
      distances[static_cast<std::size_t>(0.99 * static_cast<double>(distances.size() - 1))];
  result.mean = std::accumulate(distances.begin(), distances.end(), 0.0) /
                static_cast<double>(distances.size());
  return result;
}

/// `samples` points uniform by area over the triangles with keep_triangle set (all when empty),
/// repeatable for a seed; none when they have no area.
std::vector<Vec3> sample_by_area(std::span<const Vec3> points, std::span<const Triangle> triangles,
                                 std::span<const char> keep_triangle, std::size_t samples,
                                 std::uint64_t seed) {
  std::vector<double> cumulative;
  std::vector<std::size_t> kept;
  double total_area = 0.0;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (!keep_triangle.empty() && keep_triangle[t] == 0) {
      continue;
    }
    const Triangle& tri = triangles[t];
    const Vec3& a = points[static_cast<std::size_t>(tri[0])];
    total_area += 0.5 * (points[static_cast<std::size_t>(tri[1])] - a)
                            .cross(points[static_cast<std::size_t>(tri[2])] - a)
                            .norm();
    cumulative.push_back(total_area);
    kept.push_back(t);
  }
  std::vector<Vec3> starts;
  if (kept.empty() || !(total_area > 0.0)) {
    return starts;
  }
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  starts.resize(samples);
  for (Vec3& start : starts) {
    const double at = uniform(random) * total_area;
    const auto index = static_cast<std::size_t>(std::min<std::ptrdiff_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), at) - cumulative.begin(),
        static_cast<std::ptrdiff_t>(kept.size()) - 1));
    const Triangle& tri = triangles[kept[index]];
    const double r1 = std::sqrt(uniform(random));
    const double r2 = uniform(random);
    start = (1.0 - r1) * points[static_cast<std::size_t>(tri[0])] +
            r1 * (1.0 - r2) * points[static_cast<std::size_t>(tri[1])] +
            r1 * r2 * points[static_cast<std::size_t>(tri[2])];
  }
  return starts;
}

}  // namespace

SurfaceComponents surface_components(const SurfaceMesh& surface) {
  const std::size_t count = surface.triangles.size();
  std::map<std::pair<VertexId, VertexId>, int> first_with_edge;
  DisjointSets sets(count);
  for (std::size_t t = 0; t < count; ++t) {
    for (std::size_t e = 0; e < 3; ++e) {
      const auto key = std::minmax(surface.triangles[t][e], surface.triangles[t][(e + 1) % 3]);
      const auto [it, added] = first_with_edge.emplace(key, static_cast<int>(t));
      if (!added) {
        sets.join(static_cast<VertexId>(t), it->second);
      }
    }
  }
  SurfaceComponents result;
  result.triangle_component.assign(count, -1);
  std::map<VertexId, int> component_of_root;
  for (std::size_t t = 0; t < count; ++t) {
    const auto [it, added] = component_of_root.emplace(sets.find(static_cast<VertexId>(t)),
                                                       static_cast<int>(result.components.size()));
    if (added) {
      result.components.emplace_back();
    }
    result.triangle_component[t] = it->second;
    SurfaceComponent& component = result.components[static_cast<std::size_t>(it->second)];
    const Vec3& a = surface.points[static_cast<std::size_t>(surface.triangles[t][0])];
    const Vec3& b = surface.points[static_cast<std::size_t>(surface.triangles[t][1])];
    const Vec3& c = surface.points[static_cast<std::size_t>(surface.triangles[t][2])];
    ++component.triangles;
    component.area += 0.5 * (b - a).cross(c - a).norm();
    component.volume += a.dot(b.cross(c)) / 6.0;
  }
  return result;
}

std::vector<char> triangles_of(const SurfaceComponents& parts,
                               std::span<const char> keep_component) {
  std::vector<char> keep(parts.triangle_component.size());
  for (std::size_t t = 0; t < keep.size(); ++t) {
    keep[t] = keep_component[static_cast<std::size_t>(parts.triangle_component[t])];
  }
  return keep;
}

SurfaceMesh select_triangles(const SurfaceMesh& surface, std::span<const char> keep_triangle) {
  SurfaceMesh result;
  std::vector<VertexId> renumber(surface.points.size(), kInvalidId);
  for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
    if (keep_triangle[t] == 0) {
      continue;
    }
    Triangle out{};
    for (std::size_t c = 0; c < 3; ++c) {
      const auto v = static_cast<std::size_t>(surface.triangles[t][c]);
      if (renumber[v] == kInvalidId) {
        renumber[v] = static_cast<VertexId>(result.points.size());
        result.points.push_back(surface.points[v]);
      }
      out[c] = renumber[v];
    }
    result.triangles.push_back(out);
  }
  return result;
}

namespace {

/// Whether a grid-frame point lies within one voxel of the scan's border, where the surface
/// closes against the volume's edge (not anatomy).
bool near_scan_border(const imaging::VolumeImage& image, const Vec3& grid_mm) {
  for (Eigen::Index axis = 0; axis < 3; ++axis) {
    const double last =
        static_cast<double>(image.size[static_cast<std::size_t>(axis)] - 1) * image.spacing[axis];
    if (grid_mm[axis] < image.spacing[axis] || grid_mm[axis] > last - image.spacing[axis]) {
      return true;
    }
  }
  return false;
}

}  // namespace

IsosurfaceDistance measure_isosurface_distance(const imaging::VolumeImage& image, double iso,
                                               const SurfaceMesh& surface,
                                               std::span<const char> keep_triangle,
                                               std::size_t samples, std::uint64_t seed,
                                               double least_region_mm3) {
  IsosurfaceDistance result;
  // The surface in the grid's frame, where the image is sampled.
  std::vector<Vec3> grid_points(surface.points.size());
  for (std::size_t i = 0; i < grid_points.size(); ++i) {
    grid_points[i] = image.direction.transpose() * (surface.points[i] - image.origin);
  }

  // Isosurface to model.
  // Crossings around enclosed regions (airways, sinuses, marrow) are counted apart: the model
  // is the body's (or the bones') outer surface, and the nearest model point to a cavity's wall
  // says nothing about the model's accuracy.
  const std::vector<std::uint8_t> outside = imaging::outside_of(image, iso);
  // So are crossings around specks above iso smaller than the model holds: unmeshed (below
  // the mesher's size) or left out (below the plan's least segment), they are not the model's
  // error (2,070 of the bone's 100k samples on the 256 phantom).
  const double voxel_mm3 = image.spacing.x() * image.spacing.y() * image.spacing.z();
  const auto least_voxels = least_region_mm3 > 0.0 && voxel_mm3 > 0.0
                                ? static_cast<std::size_t>(std::ceil(least_region_mm3 / voxel_mm3))
                                : std::size_t{0};
  const std::vector<std::uint8_t> small =
      least_voxels > 1 ? imaging::small_regions_above(image, iso, least_voxels)
                       : std::vector<std::uint8_t>{};
  const imaging::IsoCrossings crossings =
      imaging::iso_crossings(image, iso, samples, seed, &outside, small.empty() ? nullptr : &small);
  result.isosurface_crossings = crossings.total;
  {
    const NearestTriangle nearest(grid_points, surface.triangles);
    std::vector<double> distance(crossings.points.size(), -1.0);
    tbb::parallel_for(std::size_t{0}, crossings.points.size(), [&](std::size_t i) {
      if (near_scan_border(image, crossings.points[i])) {
        distance[i] = -2.0;
        return;
      }
      if (crossings.enclosed[i] != 0) {
        distance[i] = -3.0;
        return;
      }
      if (!crossings.on_small_region.empty() && crossings.on_small_region[i] != 0) {
        distance[i] = -4.0;
        return;
      }
      const NearestTriangle::Hit hit = nearest.closest(crossings.points[i]);
      if (keep_triangle[static_cast<std::size_t>(hit.triangle)] != 0) {
        distance[i] = (hit.point - crossings.points[i]).norm();
      }
    });
    const auto left_out =
        static_cast<std::size_t>(std::count(distance.begin(), distance.end(), -1.0));
    const auto at_border =
        static_cast<std::size_t>(std::count(distance.begin(), distance.end(), -2.0));
    const auto enclosed =
        static_cast<std::size_t>(std::count(distance.begin(), distance.end(), -3.0));
    const auto on_small =
        static_cast<std::size_t>(std::count(distance.begin(), distance.end(), -4.0));
    std::erase_if(distance, [](double d) { return d < 0.0; });
    result.isosurface_to_model = summarize(std::move(distance));
    result.isosurface_to_model.left_out = left_out;
    result.isosurface_to_model.enclosed = enclosed;
    result.isosurface_to_model.on_small_regions = on_small;
    result.isosurface_to_model.at_scan_border = at_border;
  }

  // Model to isosurface: points uniform by area over the kept triangles.
  const std::vector<Vec3> starts =
      sample_by_area(grid_points, surface.triangles, keep_triangle, samples, seed);
  if (!starts.empty()) {
    std::vector<double> distance(samples, -1.0);
    tbb::parallel_for(std::size_t{0}, samples, [&](std::size_t i) {
      if (near_scan_border(image, starts[i])) {
        distance[i] = -2.0;
        return;
      }
      Vec3 on = starts[i];
      if (imaging::project_to_isosurface(image, iso, on)) {
        distance[i] = (on - starts[i]).norm();
      }
    });
    const auto unresolved =
        static_cast<std::size_t>(std::count(distance.begin(), distance.end(), -1.0));
    const auto at_border =
        static_cast<std::size_t>(std::count(distance.begin(), distance.end(), -2.0));
    std::erase_if(distance, [](double d) { return d < 0.0; });
    result.model_to_isosurface = summarize(std::move(distance));
    result.model_to_isosurface.unresolved = unresolved;
    result.model_to_isosurface.at_scan_border = at_border;
  }
  const std::size_t fewest = std::max<std::size_t>(
      1, std::min(result.model_to_isosurface.samples, result.isosurface_to_model.samples));
  result.beyond_max_fraction = std::log(100.0) / static_cast<double>(fewest);
  return result;
}

SurfaceDistance measure_surface_distance(const SurfaceMesh& model, const SurfaceMesh& reference,
                                         std::size_t samples, std::uint64_t seed) {
  SurfaceDistance result;
  auto one_way = [samples](const SurfaceMesh& from, const SurfaceMesh& to, std::uint64_t draw) {
    const std::vector<Vec3> starts = sample_by_area(from.points, from.triangles, {}, samples, draw);
    const NearestTriangle nearest(to.points, to.triangles);
    std::vector<double> distance(starts.size());
    tbb::parallel_for(std::size_t{0}, starts.size(), [&](std::size_t i) {
      distance[i] = (nearest.closest(starts[i]).point - starts[i]).norm();
    });
    return summarize(std::move(distance));
  };
  result.model_to_reference = one_way(model, reference, seed);
  result.reference_to_model = one_way(reference, model, seed + 1);
  const std::size_t fewest = std::max<std::size_t>(
      1, std::min(result.model_to_reference.samples, result.reference_to_model.samples));
  result.beyond_max_fraction = std::log(100.0) / static_cast<double>(fewest);
  return result;
}

}  // namespace incise::planning
