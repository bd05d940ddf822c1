// Checkpoints: the engine's complete state in one file.
//
// Layout: "INCISE-CHECKPOINT\n", format version (u32), payload size (u64), CRC-32 of the
// payload (u32), payload. The payload holds the scene (path and JSON), then the state each
// part wrote with StateWriter, in a fixed order; the CRC catches corruption before any of it
// is read, and every read is bounds-checked besides.

#include <zlib.h>

#include <fstream>
#include <iterator>

#include "engine_parts.hpp"
#include "incise/core/error.hpp"
#include "incise/cut/subdivision_cutter.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/solve/integrators.hpp"

namespace incise {
namespace {

constexpr std::string_view kMagic = "INCISE-CHECKPOINT\n";
constexpr std::uint32_t kVersion = 8;  // 2: swept triangles carry their sweep number; 3: xfem;
                                       // 4: xfem quads' shared lines decided exactly;
                                       // 5: the blade's frame, rest pose and world-to-rest map;
                                       // 6: the two-level preconditioner's state;
                                       // 7: its three-level V-cycle (the coarse blocks);
                                       // 8: its levels of groups, made again on reading

std::uint32_t checksum(std::string_view bytes) {
  uLong crc = crc32(0L, Z_NULL, 0);
  std::size_t offset = 0;
  while (offset < bytes.size()) {  // zlib takes 32-bit lengths
    const auto chunk = static_cast<uInt>(std::min<std::size_t>(bytes.size() - offset, 1U << 30));
    crc = crc32(crc, reinterpret_cast<const Bytef*>(bytes.data() + offset), chunk);
    offset += chunk;
  }
  return static_cast<std::uint32_t>(crc);
}

}  // namespace

void Engine::save_checkpoint(const std::filesystem::path& path) const {
  write_file_atomically(path, save_state());
}

std::string Engine::save_state() const {
  const Parts& p = *parts_;
  StateWriter out;
  out.tag("scene");
  out.text(p.description.file.string());
  out.text(p.description.source_text);
  out.tag("engine");
  out.value(p.last);
  out.value(p.state.time);
  out.value(p.blade.has_value());
  out.value(p.blade ? *p.blade : BladePose{0.0, Vec3::Zero(), Vec3::Zero()});
  out.value(static_cast<std::uint8_t>(p.blade_frame));
  out.value(p.blade_rest.has_value());
  out.value(p.blade_rest ? *p.blade_rest : BladePose{0.0, Vec3::Zero(), Vec3::Zero()});
  out.value(p.rest_map.linear);
  out.value(p.rest_map.offset);
  // A scripted or recorded path goes along, so a run fed by --tool resumes on it too; a live
  // source does not (the resumed run is given one).
  const auto* scripted = dynamic_cast<const ScriptedToolPath*>(p.tool.get());
  out.value(scripted != nullptr);
  out.values(scripted != nullptr ? scripted->poses() : std::vector<BladePose>{});
  p.mesh.save_state(out);
  out.tag("integrator");
  out.text(p.integrator->name());
  p.integrator->save_state(out);
  out.value(p.cutter != nullptr);
  if (p.cutter) {
    p.cutter->save_state(out);
  }
  out.value(p.xfem != nullptr);
  if (p.xfem) {
    p.xfem->save_state(out);
  }
  out.tag("end");
  return checkpoint_with_state(out.bytes());
}

std::string Engine::checkpoint_with_state(std::string_view state) {
  StateWriter header;
  header.value(kVersion);
  header.value(static_cast<std::uint64_t>(state.size()));
  header.value(checksum(state));
  return std::string(kMagic) + header.bytes() + std::string(state);
}

std::unique_ptr<Engine> Engine::resume(const std::filesystem::path& path) {
  std::ifstream stream(path, std::ios::binary);
  if (!stream) {
    throw InputError(path.string(), 0, "cannot open the checkpoint");
  }
  const std::string file((std::istreambuf_iterator<char>(stream)),
                         std::istreambuf_iterator<char>());
  return restore_state(file, path.string());
}

std::unique_ptr<Engine> Engine::restore_state(std::string_view file, const std::string& name) {
  const std::size_t header =
      kMagic.size() + sizeof(std::uint32_t) + sizeof(std::uint64_t) + sizeof(std::uint32_t);
  if (file.size() < header || file.substr(0, kMagic.size()) != kMagic) {
    throw InputError(name, 0, "not an incise checkpoint (no INCISE-CHECKPOINT header)");
  }
  StateReader head(file.substr(kMagic.size(), header - kMagic.size()), name);
  const auto version = head.value<std::uint32_t>("format version");
  const auto size = head.value<std::uint64_t>("payload size");
  const auto crc = head.value<std::uint32_t>("checksum");
  if (version != kVersion) {
    throw InputError(name, 0,
                     "checkpoint format " + std::to_string(version) + ", this incise reads " +
                         std::to_string(kVersion));
  }
  if (size != file.size() - header) {
    throw InputError(name, 0,
                     "checkpoint truncated or padded: " + std::to_string(file.size() - header) +
                         " bytes of state, the header says " + std::to_string(size));
  }
  const std::string_view payload = file.substr(header);
  if (checksum(payload) != crc) {
    throw InputError(name, 0, "checkpoint corrupted: its checksum does not match");
  }

  StateReader in(payload, name);
  in.tag("scene");
  const std::filesystem::path scene_file = in.text("scene path");
  const std::string scene_text = in.text("scene");
  auto engine = std::make_unique<Engine>(parse_scene(scene_text, scene_file));
  Parts& p = *engine->parts_;
  in.tag("engine");
  p.last = in.value<FrameRecord>("last frame");
  p.state.time = in.value<double>("time");
  const bool has_blade = in.value<bool>("blade present");
  const auto blade = in.value<BladePose>("blade");
  p.blade = has_blade ? std::optional<BladePose>(blade) : std::nullopt;
  p.blade_world.reset();
  const auto frame = in.value<std::uint8_t>("blade frame");
  if (frame > static_cast<std::uint8_t>(PoseFrame::kWorld)) {
    in.fail("blade frame", "neither the rest frame nor the world");
  }
  p.blade_frame = static_cast<PoseFrame>(frame);
  const bool has_rest_blade = in.value<bool>("rest blade present");
  const auto rest_blade = in.value<BladePose>("rest blade");
  p.blade_rest = has_rest_blade ? std::optional<BladePose>(rest_blade) : std::nullopt;
  p.rest_map.linear = in.value<Mat3>("world-to-rest map");
  p.rest_map.offset = in.value<Vec3>("world-to-rest offset");
  if (!p.rest_map.linear.allFinite() || !p.rest_map.offset.allFinite() ||
      (p.blade_rest && (!p.blade_rest->tip.allFinite() || !p.blade_rest->base.allFinite()))) {
    in.fail("world-to-rest map", "holds a value that is not finite");
  }
  const bool scripted = in.value<bool>("tool kind");
  std::vector<BladePose> poses = in.values<BladePose>("tool path");
  if (scripted) {
    p.tool = std::make_unique<ScriptedToolPath>(std::move(poses));
  }
  p.mesh.load_state(in);
  in.tag("integrator");
  if (in.text("integrator name") != p.integrator->name()) {
    in.fail("integrator name", "the checkpoint's integrator is not this scene's");
  }
  p.integrator->load_state(in);
  const bool has_cutter = in.value<bool>("cutter present");
  if (has_cutter != (p.cutter != nullptr)) {
    in.fail("cutter present", "the checkpoint and its scene disagree on the cutter");
  }
  if (p.cutter) {
    p.cutter->load_state(in);
  }
  if (in.value<bool>("xfem cutter present") != (p.xfem != nullptr)) {
    in.fail("xfem cutter present", "the checkpoint and its scene disagree on the cutter");
  }
  if (p.xfem) {
    p.xfem->load_state(in);
    for (VisualSurface* surface : {p.visual.get(), p.collision.get()}) {
      if (surface != nullptr) {
        surface->follow(p.mesh, *p.xfem);  // rebuilt from the cut, never stored
      }
    }
  }
  in.tag("end");
  if (!in.at_end()) {
    in.fail("the end", "bytes follow the end of the state");
  }
  return engine;
}

CheckpointSink::CheckpointSink(std::filesystem::path path, int every)
    : path_(std::move(path)), every_(every) {}

bool CheckpointSink::frame(const Engine& engine, const FrameRecord& record) {
  if (every_ > 0 && record.frame % every_ == 0) {
    engine.save_checkpoint(path_);
    written_frame_ = record.frame;
  }
  return false;
}

void CheckpointSink::end(const Engine& engine) {
  if (!engine.diverged() && written_frame_ != engine.frame()) {
    engine.save_checkpoint(path_);
    written_frame_ = engine.frame();
  }
}

}  // namespace incise
