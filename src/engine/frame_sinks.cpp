#include <fmt/format.h>

#include <algorithm>

#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"
#include "incise/engine/engine.hpp"
#include "incise/engine/frame_sink.hpp"
#include "incise/xfem/clipped_elements.hpp"
#include "incise/xfem/visual_surface.hpp"
#include "incise/xfem/xfem_cutter.hpp"

namespace incise {
namespace {

std::filesystem::path created(const std::filesystem::path& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) {
    throw InputError(dir.string(), 0, "cannot create the output folder: " + error.message());
  }
  return dir;
}

/// m per unit: a scene's lengths are metres (a mesh file's own unit is scaled by its "scale").
constexpr double kSceneLengthUnit = 1.0;

}  // namespace

void write_clipped_vtu(const std::filesystem::path& path, const ClippedElements& clipped,
                       std::optional<double> time, std::optional<double> length_unit_m) {
  VtuFields fields;
  fields.time = time;
  fields.length_unit_m = length_unit_m;
  fields.cell_data.push_back(
      {"element", 1, std::vector<std::int32_t>(clipped.element.begin(), clipped.element.end())});
  fields.cell_data.push_back({"fraction", 1, clipped.fraction});
  write_vtu(path, clipped.points, clipped.tets, fields);
}

VtuSeriesSink::VtuSeriesSink(const std::filesystem::path& dir, std::string name, int every,
                             int last_frame, bool continue_series)
    : dir_(created(dir)),
      name_(std::move(name)),
      every_(std::max(1, every)),
      last_frame_(last_frame),
      continue_series_(continue_series),
      series_(dir_ / (name_ + ".pvd")),
      visual_series_(dir_ / (name_ + "_visual.pvd")),
      clipped_series_(dir_ / (name_ + "_clipped.pvd")) {
  for (PvdSeries* series : {&series_, &visual_series_, &clipped_series_}) {
    series->set_length_unit(kSceneLengthUnit);
  }
}

void VtuSeriesSink::write(const Engine& engine) {
  const TetMesh& mesh = engine.mesh();
  const SimulationState& state = engine.state();
  const std::size_t n = mesh.vertex_count();
  std::vector<double> displacement(3 * n);
  std::vector<double> velocity(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = state.x.values()[i] - mesh.rest_position(static_cast<VertexId>(i));
    const Vec3& v = state.v.values()[i];
    for (int k = 0; k < 3; ++k) {
      displacement[3 * i + static_cast<std::size_t>(k)] = d[k];
      velocity[3 * i + static_cast<std::size_t>(k)] = v[k];
    }
  }
  VtuFields fields;
  fields.time = engine.time();
  fields.length_unit_m = kSceneLengthUnit;
  fields.point_data.push_back({"displacement", 3, std::move(displacement)});
  fields.point_data.push_back({"velocity", 3, std::move(velocity)});
  // A body of several materials shows which is where (ParaView: colour by "material").
  if (const MaterialMap* materials = engine.materials();
      materials != nullptr && materials->table().size() > 1) {
    std::vector<std::int32_t> ids(mesh.tet_count());
    for (std::size_t t = 0; t < ids.size(); ++t) {
      ids[t] = materials->id(static_cast<TetId>(t));
    }
    fields.cell_data.push_back({"material", 1, std::move(ids)});
  }
  // Virtual elements (XFEM) hold part of their rest tetrahedron: ParaView can threshold the
  // material fraction, or weigh by it. Written from the first frame of an XFEM body (ParaView's
  // series reader offers the arrays of the first file only).
  if (engine.xfem_cutter() != nullptr ||
      std::any_of(mesh.material_fractions().begin(), mesh.material_fractions().end(),
                  [](double fraction) { return fraction < 1.0; })) {
    fields.cell_data.push_back(
        {"fraction", 1,
         std::vector<double>(mesh.material_fractions().begin(), mesh.material_fractions().end())});
  }
  // Global frame numbers: a resumed run continues the same series.
  const std::string file = fmt::format("{}_{:06d}.vtu", name_, engine.frame());
  write_vtu(dir_ / file, mesh, state.x.values(), fields);
  series_.add(engine.time(), file);
  // The elements clipped to their sides: non-overlapping tetrahedra a volume integral counts
  // once (ParaView's Integrate Variables gives the body's true volume).
  if (const XfemCutter* cutter = engine.xfem_cutter()) {
    const std::string clipped_file = fmt::format("{}_clipped_{:06d}.vtu", name_, engine.frame());
    write_clipped_vtu(dir_ / clipped_file, clip_virtual_elements(mesh, *cutter, state.x.values()),
                      engine.time(), kSceneLengthUnit);
    clipped_series_.add(engine.time(), clipped_file);
  }
  // The embedded visual surface at the same frames: its own series (ParaView opens both).
  if (const VisualSurface* visual = engine.visual()) {
    VtuFields surface_fields;
    surface_fields.time = engine.time();
    surface_fields.length_unit_m = kSceneLengthUnit;
    surface_fields.cell_data.push_back(
        {"on_cut", 1, std::vector<std::int32_t>(visual->on_cut().begin(), visual->on_cut().end())});
    const std::string surface_file = fmt::format("{}_visual_{:06d}.vtp", name_, engine.frame());
    write_vtp(dir_ / surface_file, visual->positions(state.x.values()), visual->triangles(),
              surface_fields);
    visual_series_.add(engine.time(), surface_file);
  }
  written_frame_ = engine.frame();
}

void VtuSeriesSink::begin(const Engine& engine) {
  if (continue_series_) {
    series_.keep_existing_before(engine.time());
    if (engine.visual() != nullptr) {
      visual_series_.keep_existing_before(engine.time());
    }
    if (engine.xfem_cutter() != nullptr) {
      clipped_series_.keep_existing_before(engine.time());
    }
  }
  write(engine);
}

bool VtuSeriesSink::frame(const Engine& engine, const FrameRecord& record) {
  if (record.frame % every_ != 0 && record.frame != last_frame_) {
    return false;
  }
  write(engine);
  return true;
}

void VtuSeriesSink::end(const Engine& engine) {
  // The last frame, unless written already; a diverged frame is never written.
  if (!engine.diverged() && written_frame_ != engine.frame()) {
    write(engine);
  }
}

ToolPathRecorder::ToolPathRecorder(std::filesystem::path csv) : csv_(std::move(csv)) {}

void ToolPathRecorder::begin(const Engine& engine) {
  if (engine.blade_rest()) {
    poses_.push_back(*engine.blade_rest());
  }
}

bool ToolPathRecorder::frame(const Engine& engine, const FrameRecord& /*record*/) {
  if (engine.blade_rest()) {
    poses_.push_back(*engine.blade_rest());
  }
  return false;
}

void ToolPathRecorder::end(const Engine& /*engine*/) {
  write_blade_path(csv_, poses_);
}

}  // namespace incise
