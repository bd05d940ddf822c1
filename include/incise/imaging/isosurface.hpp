#pragma once
// Isosurfaces of a CT volume: the skin and bone surfaces of a plan. CGAL's Delaunay-refinement
// mesher samples the trilinearly interpolated image (Mesh_3 on a gray-image domain), so the
// triangles are well shaped and lie within a stated distance of the isosurface; no marching
// cubes staircase and no slivers to decimate away. Where the tissue leaves the scanned region
// the surface is left open: the triangles that would close it against the volume's border are
// not anatomy.

#include <cstdint>
#include <string>

#include "incise/imaging/volume_image.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::imaging {

/// How extract_isosurface meshes an iso value (plan key `isosurface`; CGAL Mesh_3's criteria).
struct IsosurfaceOptions {
  double facet_size = 0.0;      ///< mm, largest triangle circumradius; 0: the largest spacing
  double facet_distance = 0.0;  ///< mm, centre to isosurface at most; 0: half the least spacing
  double facet_angle = 25.0;    ///< degrees, smallest triangle angle aimed for
  /// Leaves out the triangles past the outermost voxel centres (the surface's closure against
  /// the volume's border, where the tissue leaves the scanned region).
  bool open_at_scan_border = true;
  std::uint32_t seed = 0;  ///< the mesher's random seed (results repeat for a seed)
  /// Seeds every connected region above the iso value (CGAL's search of the image: about 3 s
  /// per iso value on a 512 x 512 x 300 CT). Off, CGAL's random rays from the volume's middle
  /// seed it: enough for an image known to hold one region whose surface they meet.
  bool seed_every_region = true;
};

/// An image's isosurface and what making it found.
struct Isosurface {
  SurfaceMesh surface;               ///< mm, patient space
  std::size_t border_triangles = 0;  ///< left out at the scan border
  std::size_t voxels_inside = 0;     ///< voxels whose value exceeds the iso value
  /// Every connected region above the iso value was seeded; false: CGAL's region seeding
  /// failed and its default seeding (random rays from the middle, which can miss a small
  /// region) made the surface.
  bool every_region_seeded = true;
};

/// The surface where the image crosses `iso` (inside: values above it); every connected region
/// above it is seeded, so no bone is missed. CGAL's seeding prints three progress lines to
/// std::cout (run_plan sends them nowhere). Throws InputError,
/// naming `what`, when no voxel (or every voxel) exceeds the iso value.
[[nodiscard]] Isosurface extract_isosurface(const VolumeImage& image, double iso,
                                            const IsosurfaceOptions& options,
                                            const std::string& what);

}  // namespace incise::imaging
