#include "fuzz_targets.hpp"

#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include "incise/core/error.hpp"
#include "incise/cut/blade.hpp"
#include "incise/engine/engine.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/planning/plan.hpp"
#include "incise/scene/scene.hpp"
#include "incise/view/session_recording.hpp"
#ifdef INCISE_FUZZ_IMAGING
#include "incise/imaging/read_volume.hpp"
#endif
#ifdef INCISE_FUZZ_IGTL
#include "incise/igtl/wire.hpp"
#endif

namespace incise::fuzz {
namespace {

/// The readers take paths (as users give them), so each input becomes a file in a folder of
/// this process's own.
std::filesystem::path input_file(const char* extension) {
  static const std::filesystem::path folder = [] {
    auto path = std::filesystem::temp_directory_path() /
                ("incise-fuzz-" + std::to_string(static_cast<long>(getpid())));
    std::filesystem::create_directories(path);
    return path;
  }();
  return folder / (std::string("input") + extension);
}

std::filesystem::path write_input(std::string_view bytes, const char* extension) {
  const auto path = input_file(extension);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}

template <const char* kExtension>
void mesh(std::string_view bytes) {
  const auto path = write_input(bytes, kExtension);
  const RawMesh raw = read_raw_mesh(path);
  if (!raw.tets.empty()) {
    (void)read_tet_mesh(path);  // and the checks that make a TetMesh of it
  } else if (!raw.triangles.empty()) {
    (void)read_surface(path);
  }
}

constexpr char kMsh[] = ".msh";
constexpr char kVtk[] = ".vtk";
constexpr char kVtu[] = ".vtu";
constexpr char kMedit[] = ".mesh";
constexpr char kNode[] = ".node";
constexpr char kObj[] = ".obj";
constexpr char kStl[] = ".stl";
constexpr char kPly[] = ".ply";
constexpr char kOff[] = ".off";

void scene(std::string_view bytes) {
  (void)load_scene(write_input(bytes, ".json"));
}
void plan(std::string_view bytes) {
  (void)planning::load_plan(write_input(bytes, ".json"));
}
void blade_path(std::string_view bytes) {
  (void)read_blade_path(write_input(bytes, ".csv"));
}
void session(std::string_view bytes) {
  (void)read_session(write_input(bytes, ".jsonl"));
}
void checkpoint(std::string_view bytes) {
  (void)Engine::resume(write_input(bytes, ".ckpt"));
}
/// The state behind a valid header: what a checkpoint written by a faulty (or hostile) writer
/// would hold, past the checksum that stops random corruption.
void checkpoint_state(std::string_view bytes) {
  (void)Engine::resume(write_input(Engine::checkpoint_with_state(bytes), ".ckpt"));
}

#ifdef INCISE_FUZZ_IMAGING
void metaimage(std::string_view bytes) {
  (void)imaging::read_volume(write_input(bytes, ".mha"));
}
void dicom(std::string_view bytes) {
  (void)imaging::read_volume(write_input(bytes, ".dcm"));
}
#endif

#ifdef INCISE_FUZZ_IGTL
/// A byte stream as the server receives it: split into messages, each decoded as its type.
void igtl_stream(std::string_view bytes) {
  igtl::MessageReader reader;
  const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
  // Fed in uneven pieces, as a socket delivers them.
  std::size_t offset = 0;
  for (std::size_t piece = 1; offset < bytes.size(); piece = piece * 3 % 97 + 1) {
    const std::size_t size = std::min(piece, bytes.size() - offset);
    reader.feed(std::span<const std::uint8_t>(data + offset, size));
    offset += size;
    while (const auto event = reader.next()) {
      if (const auto* message = std::get_if<igtl::Message>(&*event)) {
        (void)igtl::check_message(*message);
        (void)igtl::decode_transform(*message);
        (void)igtl::decode_sensor(*message);
        (void)igtl::decode_status(*message);
        (void)igtl::decode_surface(*message);
      }
    }
    if (reader.fatal()) {
      return;
    }
  }
}
#endif

constexpr std::array kTargets{
    Target{"mesh_msh", kMsh, mesh<kMsh>},
    Target{"mesh_vtk", kVtk, mesh<kVtk>},
    Target{"mesh_vtu", kVtu, mesh<kVtu>},
    Target{"mesh_medit", kMedit, mesh<kMedit>},
    Target{"mesh_tetgen", kNode, mesh<kNode>},
    Target{"mesh_obj", kObj, mesh<kObj>},
    Target{"mesh_stl", kStl, mesh<kStl>},
    Target{"mesh_ply", kPly, mesh<kPly>},
    Target{"mesh_off", kOff, mesh<kOff>},
    Target{"scene", ".json", scene},
    Target{"plan", ".json", plan},
    Target{"blade_path", ".csv", blade_path},
    Target{"session", ".jsonl", session},
    Target{"checkpoint", ".ckpt", checkpoint},
    Target{"checkpoint_state", ".state", checkpoint_state},
#ifdef INCISE_FUZZ_IMAGING
    Target{"metaimage", ".mha", metaimage},
    Target{"dicom", ".dcm", dicom},
#endif
#ifdef INCISE_FUZZ_IGTL
    Target{"igtl", ".igtl", igtl_stream},
#endif
};

}  // namespace

std::span<const Target> targets() {
  return kTargets;
}

const Target* find_target(std::string_view name) {
  for (const Target& target : kTargets) {
    if (name == target.name) {
      return &target;
    }
  }
  return nullptr;
}

void run_one(const Target& target, std::string_view bytes) {
  try {
    target.run(bytes);
  } catch (const InputError&) {
    // The expected answer to bad input.
  } catch (const std::exception& error) {
    std::fprintf(stderr, "fuzz target %s: not an InputError: %s\n", target.name, error.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "fuzz target %s: unknown exception\n", target.name);
    std::abort();
  }
}

}  // namespace incise::fuzz
