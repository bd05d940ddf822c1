#include "tissue_output.hpp"

#include <fmt/format.h>

#include <string>

#include "incise/core/error.hpp"

namespace incise::planning {

namespace {
constexpr double kToMillimetres = 1e3;
}  // namespace

void write_surface_mm(const std::filesystem::path& path, std::span<const Vec3> points,
                      std::span<const Triangle> triangles, std::span<const Vec3> before,
                      std::span<const int> cell_segment) {
  std::vector<Vec3> millimetres(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    millimetres[i] = points[i] * kToMillimetres;
  }
  VtuFields fields;
  fields.length_unit_m = 1.0 / kToMillimetres;
  if (!before.empty()) {
    std::vector<double> displacement;
    std::vector<double> magnitude;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Vec3 d = (points[i] - before[i]) * kToMillimetres;
      displacement.insert(displacement.end(), {d.x(), d.y(), d.z()});
      magnitude.push_back(d.norm());
    }
    fields.point_data.push_back({"displacement", 3, std::move(displacement)});
    fields.point_data.push_back({"displacement_magnitude", 1, std::move(magnitude)});
  }
  if (!cell_segment.empty()) {
    fields.cell_data.push_back(
        {"segment", 1, std::vector<std::int32_t>(cell_segment.begin(), cell_segment.end())});
  }
  write_vtp(path, millimetres, triangles, fields);
}

void write_bone_mm(const std::filesystem::path& path, const SurfaceMesh& bone,
                   const BoneSegments& segments, std::span<const RigidMove> segment_moves) {
  std::vector<Vec3> points;
  std::vector<Triangle> triangles;
  std::vector<int> cell_segment;
  // (segment, vertex) -> written point.
  std::vector<std::vector<VertexId>> renumber(static_cast<std::size_t>(segments.count),
                                              std::vector<VertexId>(bone.points.size(), -1));
  for (std::size_t t = 0; t < bone.triangles.size(); ++t) {
    const int segment = segments.triangle_segment[t];
    auto& map = renumber[static_cast<std::size_t>(segment)];
    Triangle out{};
    for (int c = 0; c < 3; ++c) {
      const auto v = static_cast<std::size_t>(bone.triangles[t][static_cast<std::size_t>(c)]);
      if (map[v] < 0) {
        map[v] = static_cast<VertexId>(points.size());
        points.push_back(
            segment_moves.empty()
                ? bone.points[v]
                : segment_moves[static_cast<std::size_t>(segment)].apply(bone.points[v]));
      }
      out[static_cast<std::size_t>(c)] = map[v];
    }
    triangles.push_back(out);
    cell_segment.push_back(segment);
  }
  write_surface_mm(path, points, triangles, {}, cell_segment);
}

void write_tissue_vtu_mm(const std::filesystem::path& path, const LayeredTissue& tissue,
                         std::span<const Vec3> x) {
  // ASCII: the model is small, and wedges are not a TetMesh for write_vtu.
  std::string text;
  text +=
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
      "byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n";
  // The unit as every incise file says it (io/mesh_io.hpp: LengthUnitInMetres).
  text +=
      "<FieldData>\n<!-- incise: point coordinates in mm -->\n<DataArray type=\"Float64\" "
      "Name=\"LengthUnitInMetres\" NumberOfTuples=\"1\" format=\"ascii\">0.001</DataArray>\n"
      "</FieldData>\n";
  text += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", x.size(),
                      tissue.prisms.size());
  text +=
      "<PointData Scalars=\"kind\">\n<DataArray type=\"Int32\" Name=\"kind\" "
      "format=\"ascii\">\n";
  for (PointKind kind : tissue.kind) {
    text += fmt::format("{} ", static_cast<int>(kind));
  }
  text += "\n</DataArray>\n<DataArray type=\"Int32\" Name=\"layer\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < x.size(); ++i) {
    text += fmt::format("{} ", tissue.layer_of(static_cast<int>(i)));
  }
  text +=
      "\n</DataArray>\n<DataArray type=\"Float64\" Name=\"displacement\" "
      "NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < x.size(); ++i) {
    const Vec3 d = (x[i] - tissue.rest[i]) * kToMillimetres;
    if (!d.allFinite()) {
      throw InputError(path.string() + ": refusing to write non-finite displacements");
    }
    text += fmt::format("{:.9g} {:.9g} {:.9g}\n", d.x(), d.y(), d.z());
  }
  text +=
      "</DataArray>\n</PointData>\n<CellData>\n<DataArray type=\"Int32\" Name=\"layer\" "
      "format=\"ascii\">\n";
  for (const Prism& prism : tissue.prisms) {
    text += fmt::format("{} ", prism.layer);
  }
  text +=
      "\n</DataArray>\n</CellData>\n<Points>\n<DataArray type=\"Float64\" "
      "NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const Vec3& p : x) {
    const Vec3 q = p * kToMillimetres;
    text += fmt::format("{:.9g} {:.9g} {:.9g}\n", q.x(), q.y(), q.z());
  }
  text +=
      "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" "
      "format=\"ascii\">\n";
  for (const Prism& prism : tissue.prisms) {
    // VTK's wedge: the base (0, 1, 2) with its normal away from (3, 4, 5). The outer
    // triangle of an outward skin normal is such a base.
    text += fmt::format("{} {} {} {} {} {}\n", prism.points[0], prism.points[1], prism.points[2],
                        prism.points[3], prism.points[4], prism.points[5]);
  }
  text += "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (std::size_t c = 0; c < tissue.prisms.size(); ++c) {
    text += fmt::format("{} ", 6 * (c + 1));
  }
  text += "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (std::size_t c = 0; c < tissue.prisms.size(); ++c) {
    text += "13 ";  // VTK_WEDGE
  }
  text += "\n</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  write_file_atomically(path, text);
}

}  // namespace incise::planning
