#pragma once
// What the skin and bone surfaces of a plan are worth against the CT they came from: their
// connected components (which are kept, which are left out and why), and the distance between
// a surface and the image's isosurface measured both ways by sampling.
//
// The isosurface is the level set of the trilinearly interpolated image (the field the mesher
// meets). Isosurface to model: a uniform sample of the points where the field crosses the iso
// value on the grid's edges, which lie exactly on the isosurface; each one's distance to the
// nearest model triangle. Model to isosurface: points spread uniformly by area over the model's
// triangles, each moved onto the isosurface along the field's gradient; the distance moved (an
// upper bound of its distance to the isosurface). Samples within a voxel of the scan's border,
// where the surface closes against the volume's edge, are not measured. Both are samples: with n
// samples and none beyond the largest, at most ln(100)/n of the surface lies beyond it with 99 %
// confidence.

#include <cstdint>
#include <span>
#include <vector>

#include "incise/imaging/volume_image.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::planning {

/// One connected piece of a surface.
struct SurfaceComponent {
  std::size_t triangles = 0;  ///< its triangles
  double area = 0.0;          ///< length^2, in the surface's units
  double volume = 0.0;        ///< length^3, signed: positive for outward-facing triangles (an open
                        ///< component's is that of the surface closed by a cone to the origin)
};

/// A surface's connected pieces.
struct SurfaceComponents {
  std::vector<int> triangle_component;       ///< per triangle
  std::vector<SurfaceComponent> components;  ///< the pieces
};

/// Components of triangles joined through shared edges.
[[nodiscard]] SurfaceComponents surface_components(const SurfaceMesh& surface);

/// Per triangle: whether its component is kept (keep_component, one flag per component).
[[nodiscard]] std::vector<char> triangles_of(const SurfaceComponents& parts,
                                             std::span<const char> keep_component);

/// The triangles of the chosen components, renumbered.
[[nodiscard]] SurfaceMesh select_triangles(const SurfaceMesh& surface,
                                           std::span<const char> keep_triangle);

/// The distance from one surface to another, from samples on the first.
struct OneSidedDistance {
  double max = 0.0;                  ///< mm
  double p99 = 0.0;                  ///< mm: 99 % of the samples are nearer
  double mean = 0.0;                 ///< mm
  std::size_t samples = 0;           ///< measured
  std::size_t unresolved = 0;        ///< model samples the gradient could not carry to the surface
  std::size_t left_out = 0;          ///< isosurface samples nearest a component that was left out
  std::size_t enclosed = 0;          ///< isosurface samples on an enclosed region's wall (a cavity)
  std::size_t on_small_regions = 0;  ///< isosurface samples around a region above iso smaller
                                     ///< than the least the model holds (specks)
  std::size_t at_scan_border = 0;    ///< within a voxel of the scan's border: not measured
};

/// A model surface against an image's isosurface, both ways.
struct IsosurfaceDistance {
  OneSidedDistance model_to_isosurface;  ///< from samples on the model
  OneSidedDistance isosurface_to_model;  ///< from samples on the isosurface
  std::size_t isosurface_crossings = 0;  ///< on the whole grid
  /// With 99 % confidence, at most this fraction of each surface lies beyond its largest
  /// sampled distance: ln(100) / samples.
  double beyond_max_fraction = 0.0;
};

/// Measures `surface` (mm, patient space; only the triangles with keep_triangle set are the
/// model, the others are surfaces left out) against the isosurface of `image` at `iso` with
/// `samples` samples each way. Parallel; repeats for a seed. Isosurface samples around regions
/// above iso of less than `least_region_mm3` (what the model keeps or can mesh) are counted
/// apart, not measured.
[[nodiscard]] IsosurfaceDistance measure_isosurface_distance(const imaging::VolumeImage& image,
                                                             double iso, const SurfaceMesh& surface,
                                                             std::span<const char> keep_triangle,
                                                             std::size_t samples,
                                                             std::uint64_t seed = 0,
                                                             double least_region_mm3 = 0.0);

/// Two surfaces against each other, both ways.
struct SurfaceDistance {
  OneSidedDistance model_to_reference;  ///< from samples on the model
  OneSidedDistance reference_to_model;  ///< from samples on the reference
  /// With 99 % confidence, at most this fraction of each surface lies beyond its largest
  /// sampled distance: ln(100) / samples.
  double beyond_max_fraction = 0.0;
};

/// The distance between two surfaces, both ways, by `samples` points uniform by area on each,
/// every one's distance to the nearest point of the other (in the surfaces' units). Parallel;
/// repeats for a seed.
[[nodiscard]] SurfaceDistance measure_surface_distance(const SurfaceMesh& model,
                                                       const SurfaceMesh& reference,
                                                       std::size_t samples, std::uint64_t seed = 0);

}  // namespace incise::planning
