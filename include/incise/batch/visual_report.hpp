#pragma once
// How an embedded visual (or collision) surface came through its cuts, for the reports of
// incise run, cut and serve: closed or not, and the updates that kept the last good picture.

#include <nlohmann/json.hpp>

#include "incise/mesh/boundary.hpp"
#include "incise/xfem/visual_surface.hpp"

namespace incise {

inline nlohmann::ordered_json visual_surface_report(const VisualSurface& surface) {
  const SurfaceEdgeCheck edges = check_surface_edges(surface.triangles());
  nlohmann::ordered_json json;
  json["triangles"] = surface.triangles().size();
  json["closed_manifold"] = edges.watertight();
  json["open_edges"] = edges.open_edges;
  json["nonmanifold_edges"] = edges.nonmanifold_edges;
  json["flat_triangles"] = count_flat_triangles(surface.rest_points(), surface.triangles());
  json["kept_last_picture"] = surface.failures();
  json["last_failure"] = surface.last_failure();
  return json;
}

}  // namespace incise
