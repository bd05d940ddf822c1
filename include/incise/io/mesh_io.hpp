#pragma once
// Reading and writing meshes. Readers detect the format from the content (the extension only
// breaks ties), and every malformed input raises InputError naming the file and the line (or
// element) at fault; nothing is ever returned half-read.
//
// Read: Gmsh .msh (v1, v2 ASCII/binary, v4.0 ASCII, v4.1 ASCII/binary), TetGen .node/.ele,
//       MEDIT .mesh, VTK legacy .vtk (UNSTRUCTURED_GRID and POLYDATA, ASCII and BINARY,
//       file versions up to 5.1), VTK XML .vtu/.vtp (ascii, base64, appended raw or base64,
//       zlib-compressed), OBJ, STL (ASCII and binary), PLY (ASCII and binary) and OFF surfaces.
// Write: Gmsh .msh 4.1, VTK XML .vtu with point and cell data, .pvd series, MEDIT .mesh,
//       OBJ (boundary surface), TetGen .node/.ele.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "incise/core/atomic_file.hpp"  // write_file_atomically, used by every writer
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

enum class MeshFormat {
  kUnknown,
  kGmsh,
  kTetGen,
  kMedit,
  kVtkLegacy,
  kVtkXml,
  kObj,
  kStl,
  kPly,
  kOff
};

[[nodiscard]] std::string format_name(MeshFormat format);

/// Format judged from the first bytes of the file; the extension decides only when the
/// content is ambiguous. Throws InputError if the file cannot be read.
[[nodiscard]] MeshFormat detect_format(const std::filesystem::path& path);

/// What a reader found: points, tetrahedra, triangles, and notes on anything it skipped.
struct RawMesh {
  std::vector<Vec3> points;     ///< in the file's own length unit
  std::vector<Tet> tets;        ///< point ids
  std::vector<int> tet_labels;  ///< region label per tetrahedron (0 where the file has none)
  /// XFEM material fraction per tetrahedron (a .vtu's "fraction" cell array), else empty.
  std::vector<double> tet_fractions;
  /// Per point, its displacement from the rest shape (a .vtu frame's "displacement" point
  /// array), else empty.
  std::vector<Vec3> point_displacements;
  std::vector<Triangle> triangles;  ///< point ids
  /// Human-readable notes ("skipped 120 hexahedra"), one per kind of thing skipped.
  std::vector<std::string> notes;
  MeshFormat format = MeshFormat::kUnknown;  ///< the format it was read as
};

/// Choices a reader cannot make from the file alone.
struct ReadOptions {
  /// The VTK cell array (.vtu, .vtk) to take as region labels, by name; empty: the first
  /// one-component integer cell array. A named array that is missing or not whole numbers is
  /// an error naming the arrays the file has.
  std::string label_array;
};

/// Reads any supported file as it is (ids checked against the point count).
[[nodiscard]] RawMesh read_raw_mesh(const std::filesystem::path& path,
                                    const ReadOptions& options = {});

/// A tetrahedral mesh read from a file, with what the reader noted on the way.
struct TetMeshReadResult {
  TetMesh mesh;                              ///< the mesh (the file's length unit)
  MeshFormat format = MeshFormat::kUnknown;  ///< the format it was read as
  std::vector<std::string> notes;            ///< what was skipped or dropped, one per kind
  std::size_t dropped_vertices = 0;          ///< points used by no tetrahedron, removed
  /// The rest shape of a deformed frame (points minus their "displacement"), one per vertex of
  /// `mesh`, whose positions are the frame's; empty when the file gives none.
  std::vector<Vec3> rest_positions;
};

/// Reads a tetrahedral mesh. Points used by no tetrahedron are dropped (and noted) so that
/// every vertex carries mass. Throws InputError when the file holds no tetrahedra.
[[nodiscard]] TetMeshReadResult read_tet_mesh(const std::filesystem::path& path,
                                              const ReadOptions& options = {});

/// A triangle surface read from a file.
struct SurfaceMesh {
  std::vector<Vec3> points;         ///< in the file's own length unit
  std::vector<Triangle> triangles;  ///< point ids
  std::vector<std::string> notes;   ///< what was skipped or merged, one per kind
};

/// Reads a triangle surface (OBJ, STL, PLY, VTK polydata, or the triangles of any volume
/// format). Exactly coincident points are merged (STL stores none shared). Throws InputError
/// when the file holds no triangles.
[[nodiscard]] SurfaceMesh read_surface(const std::filesystem::path& path);

/// A named array for VTK output: `components` values per point or per cell.
struct FieldArray {
  std::string name;    ///< as ParaView lists it
  int components = 1;  ///< values per point or cell
  /// components x count values, point (or cell) by point.
  std::variant<std::vector<double>, std::vector<std::int32_t>> values;
};

/// The arrays and field data written with a .vtu.
struct VtuFields {
  std::vector<FieldArray> point_data;  ///< one value (tuple) per point
  std::vector<FieldArray> cell_data;   ///< one value (tuple) per tetrahedron
  /// s: written as the file's TimeValue field data (a frame of a series), if given.
  std::optional<double> time;
  /// m per unit of the points' coordinates (1: metres, 1e-3: millimetres), written as the
  /// file's LengthUnitInMetres field data and said in a comment; left out when not known
  /// (a mesh read from a file that does not say, cut as it is).
  std::optional<double> length_unit_m;
};

/// Writes a .vtu (arrays inline, zlib-compressed, base64) of the mesh at `positions` (one per
/// vertex; empty means rest positions). Refuses NaN/Inf in positions or fields (InputError).
void write_vtu(const std::filesystem::path& path, const TetMesh& mesh,
               std::span<const Vec3> positions = {}, const VtuFields& fields = {});
/// The same for tetrahedra that need not make a mesh (they may share no point, or overlap).
void write_vtu(const std::filesystem::path& path, std::span<const Vec3> points,
               std::span<const Tet> tets, const VtuFields& fields = {});

/// A ParaView time series: each add() writes the .pvd anew so a partial run stays readable.
class PvdSeries {
 public:
  /// The series' .pvd file; nothing is written before the first add().
  explicit PvdSeries(std::filesystem::path pvd_path);
  /// Continues the series already at the path (a resumed run): keeps its entries before
  /// `time` (s), so the next add() writes one series across both runs.
  void keep_existing_before(double time);
  /// Records `file` (relative to the .pvd's folder) at time `time` (s) and rewrites the .pvd.
  void add(double time, const std::string& file);
  /// m per unit of the files' coordinates, said in a comment in the .pvd (unset: not said).
  void set_length_unit(double metres) { length_unit_m_ = metres; }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }  ///< the .pvd

 private:
  std::filesystem::path path_;
  std::vector<std::pair<double, std::string>> entries_;
  std::optional<double> length_unit_m_;
};

/// Gmsh 4.1 ASCII.
void write_msh(const std::filesystem::path& path, const TetMesh& mesh);
/// MEDIT .mesh with the boundary triangles.
void write_medit(const std::filesystem::path& path, const TetMesh& mesh);
/// The boundary surface as OBJ (only the vertices it uses).
void write_obj(const std::filesystem::path& path, const TetMesh& mesh);
void write_obj(const std::filesystem::path& path, std::span<const Vec3> points,
               std::span<const Triangle> triangles);
/// TetGen .node and .ele (0-based) next to `path` (its extension is replaced).
void write_tetgen(const std::filesystem::path& path, const TetMesh& mesh);
/// VTK XML .vtp of a triangle surface, with optional point and cell (triangle) arrays.
void write_vtp(const std::filesystem::path& path, std::span<const Vec3> points,
               std::span<const Triangle> triangles, const VtuFields& fields = {});

/// Writes by extension: .msh, .vtu, .mesh, .obj, .node/.ele. Throws InputError otherwise.
/// `length_unit_m` (m per coordinate unit, when known) goes into a .vtu's field data.
void write_tet_mesh(const std::filesystem::path& path, const TetMesh& mesh,
                    std::optional<double> length_unit_m = {});

/// A length unit's name for m per unit (1 -> "m", 0.01 -> "cm", 1e-3 -> "mm", else "x m"),
/// "mesh units" when not known: what reports and messages call lengths.
[[nodiscard]] std::string length_unit_name(std::optional<double> length_unit_m);

}  // namespace incise
