#include "incise/imaging/isosurface.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_3/initialize_triangulation_from_gray_image.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/facets_in_complex_3_to_triangle_mesh.h>
#include <CGAL/make_mesh_3.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <vector>

#include "incise/core/error.hpp"

namespace incise::imaging {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Domain = CGAL::Labeled_mesh_domain_3<Kernel>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

/// The volume as CGAL's image (float voxels, spacing in mm, no translation: the mesher works in
/// the grid's own frame and the points are placed in patient space afterwards).
CGAL::Image_3 to_cgal_image(const VolumeImage& image) {
  _image* raw =
      ::_createImage(image.size[0], image.size[1], image.size[2], 1, image.spacing.x(),
                     image.spacing.y(), image.spacing.z(), sizeof(float), WK_FLOAT, SGN_SIGNED);
  if (raw == nullptr) {
    throw InputError("not enough memory for the isosurface's image copy");
  }
  std::copy(image.values.begin(), image.values.end(), static_cast<float*>(raw->data));
  return CGAL::Image_3(raw);
}

}  // namespace

Isosurface extract_isosurface(const VolumeImage& image, double iso,
                              const IsosurfaceOptions& options, const std::string& what) {
  check_volume(image, what);
  Isosurface result;
  result.voxels_inside = static_cast<std::size_t>(
      std::count_if(image.values.begin(), image.values.end(), [&](float v) { return v > iso; }));
  const auto [low, high] = value_range(image);
  if (result.voxels_inside == 0 || result.voxels_inside == image.voxel_count()) {
    throw InputError(what, 0,
                     fmt::format("{} voxel exceeds the iso value {} (the image's values run from "
                                 "{} to {}): no surface",
                                 result.voxels_inside == 0 ? "no" : "every", iso, low, high));
  }

  const double facet_size =
      options.facet_size > 0.0 ? options.facet_size : image.spacing.maxCoeff();
  const double facet_distance =
      options.facet_distance > 0.0 ? options.facet_distance : 0.5 * image.spacing.minCoeff();
  const CGAL::Image_3 cgal_image = to_cgal_image(image);
  CGAL::Random random(options.seed);
  // The region seeding draws its ray directions from this thread's default generator, which
  // CGAL seeds from the clock: seeded here, the surface repeats for a seed on any thread.
  CGAL::get_default_random() = CGAL::Random(options.seed);
  namespace params = CGAL::parameters;
  // Outside the volume the image reads as just below the iso value, so tissue that reaches the
  // border closes just past the outermost voxel centres (that closure is left out below).
  const Domain domain = Domain::create_gray_image_mesh_domain(
      cgal_image, params::iso_value = static_cast<float>(iso),
      params::value_outside = static_cast<float>(std::min<double>(low, iso - 1.0)),
      params::p_rng = &random);
  // Only the surface is wanted: cells are left as coarse as the mesher allows.
  const Criteria criteria(params::facet_angle = options.facet_angle,
                          params::facet_size = facet_size, params::facet_distance = facet_distance);
  // Seeded from every connected region of voxels above the iso value (CGAL's default seeding
  // shoots random rays from the middle and misses bones it does not hit: a vertebra, a
  // mandible), then refined.
  // CGAL 5.5's seeding can meet a ray hit that coincides with a point already inserted and
  // stop on an assertion; then the default seeding meshes what its rays find, and the result
  // says so.
  Complex complex;
  result.every_region_seeded = options.seed_every_region;
  if (options.seed_every_region) {
    try {
      initialize_triangulation_from_gray_image(complex, domain, cgal_image, criteria,
                                               static_cast<float>(iso), float{});
    } catch (const CGAL::Failure_exception&) {
      complex = Complex();
      result.every_region_seeded = false;
    }
  }
  if (result.every_region_seeded) {
    CGAL::refine_mesh_3(complex, domain, criteria, params::no_perturb(), params::no_exude(),
                        params::manifold());
  } else {
    complex = CGAL::make_mesh_3<Complex>(domain, criteria, params::no_perturb(), params::no_exude(),
                                         params::manifold());
  }

  CGAL::Surface_mesh<Kernel::Point_3> mesh;
  CGAL::facets_in_complex_3_to_triangle_mesh(complex, mesh);

  // The box of the voxel centres in the grid's frame (mm); a triangle with all three corners
  // past one of its faces lies where the image was extrapolated.
  const double tolerance = 1e-6 * image.spacing.minCoeff();
  Vec3 box_high;
  for (int axis = 0; axis < 3; ++axis) {
    box_high[axis] =
        static_cast<double>(image.size[static_cast<std::size_t>(axis)] - 1) * image.spacing[axis];
  }
  auto past_border = [&](const std::array<Vec3, 3>& corners) {
    for (int axis = 0; axis < 3; ++axis) {
      if (std::all_of(corners.begin(), corners.end(),
                      [&](const Vec3& p) { return p[axis] <= tolerance; }) ||
          std::all_of(corners.begin(), corners.end(),
                      [&](const Vec3& p) { return p[axis] >= box_high[axis] - tolerance; })) {
        return true;
      }
    }
    return false;
  };

  std::vector<int> index_of(mesh.number_of_vertices(), -1);
  for (const auto face : mesh.faces()) {
    std::array<Vec3, 3> corners;
    std::array<int, 3> vertex_ids{};
    int corner = 0;
    for (const auto vertex : CGAL::vertices_around_face(mesh.halfedge(face), mesh)) {
      const auto& p = mesh.point(vertex);
      corners[static_cast<std::size_t>(corner)] = Vec3(p.x(), p.y(), p.z());
      vertex_ids[static_cast<std::size_t>(corner)] = static_cast<int>(vertex.idx());
      ++corner;
    }
    if (options.open_at_scan_border && past_border(corners)) {
      ++result.border_triangles;
      continue;
    }
    Triangle triangle{};
    for (std::size_t c = 0; c < 3; ++c) {
      int& id = index_of[static_cast<std::size_t>(vertex_ids[c])];
      if (id < 0) {
        id = static_cast<int>(result.surface.points.size());
        result.surface.points.push_back(image.origin + image.direction * corners[c]);
      }
      triangle[c] = static_cast<VertexId>(id);
    }
    result.surface.triangles.push_back(triangle);
  }
  if (result.surface.triangles.empty()) {
    throw InputError(what, 0,
                     fmt::format("the isosurface at {} lies entirely on the scan's border", iso));
  }
  return result;
}

}  // namespace incise::imaging
