#include "incise/mesh/summary.hpp"

#include <algorithm>

#include "incise/mesh/boundary.hpp"

namespace incise {

MeshSummary summarize(const TetMesh& mesh) {
  MeshSummary summary;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    const double volume = signed_volume(mesh, tet);
    summary.min_tet_volume = t == 0 ? volume : std::min(summary.min_tet_volume, volume);
    summary.max_tet_volume = t == 0 ? volume : std::max(summary.max_tet_volume, volume);
    const double fraction = mesh.material_fraction(tet);
    summary.volume += fraction * volume;
    summary.virtual_elements += fraction < 1.0 ? 1 : 0;
    RegionSummary& region = summary.regions[mesh.tet_label(tet)];
    ++region.tets;
    region.volume += fraction * volume;
  }
  summary.bounds = bounding_box(mesh);
  (void)tet_components(mesh, &summary.components);
  summary.boundary_triangles = boundary_faces(mesh).size();
  summary.watertight = check_boundary(mesh).watertight();
  summary.quality = summarize_quality(mesh);
  return summary;
}

}  // namespace incise
