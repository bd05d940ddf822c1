// fuzz_replay TARGET [--like FOLDER]... PATH...: runs every file (folders: every file in
// them; after --like, only files with the target's extension, such as the meshes of
// ../shared/data) through a fuzz target, as libFuzzer would, without libFuzzer. CTest replays
// the corpora with it in every build, so a past finding can never come back unseen.

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>
#include <vector>

#include "fuzz_targets.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: fuzz_replay TARGET [--like FOLDER]... FILE_OR_FOLDER...\ntargets:");
    for (const auto& target : incise::fuzz::targets()) {
      std::fprintf(stderr, " %s", target.name);
    }
    std::fprintf(stderr, "\n");
    return 2;
  }
  const auto* target = incise::fuzz::find_target(argv[1]);
  if (target == nullptr) {
    std::fprintf(stderr, "fuzz_replay: no target named '%s'\n", argv[1]);
    return 2;
  }
  std::vector<std::filesystem::path> files;
  constexpr std::uintmax_t kLargestSeed = 2U << 20U;  // bytes; larger files only slow replays
  for (int i = 2; i < argc; ++i) {
    const bool like = std::string_view(argv[i]) == "--like" && i + 1 < argc;
    const std::filesystem::path path = argv[like ? ++i : i];
    if (std::filesystem::is_directory(path)) {
      for (const auto& entry : std::filesystem::recursive_directory_iterator(path)) {
        if (entry.is_regular_file() && (!like || (entry.path().extension() == target->extension &&
                                                  entry.file_size() <= kLargestSeed))) {
          files.push_back(entry.path());
        }
      }
    } else if (std::filesystem::is_regular_file(path)) {
      files.push_back(path);
    } else {
      std::fprintf(stderr, "fuzz_replay: %s is neither a file nor a folder\n", argv[i]);
      return 2;
    }
  }
  for (const auto& file : files) {
    std::ifstream in(file, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    std::fprintf(stderr, "%s\n", file.c_str());  // the input at fault if the next one aborts
    incise::fuzz::run_one(*target, bytes.str());
  }
  std::printf("fuzz_replay %s: %zu inputs, no finding\n", target->name, files.size());
  return files.empty() ? 1 : 0;
}
