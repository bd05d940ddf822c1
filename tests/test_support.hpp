#pragma once
// Helpers shared by the tests: where the third-party test data lives, small meshes.

#include <gtest/gtest.h>

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise::test {

/// Built with AddressSanitizer (the clang CI build): physics runs some 10-20 times slower, so
/// tests that need it to keep up with the wall clock (a device streaming in real time) skip.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

/// How many seeded repeats a randomised test makes: all `full` in the optimised build, half
/// under AddressSanitizer, where each takes 10-20 times longer and the first half already
/// walks the paths a memory error would be on. The g++ run keeps the full breadth.
inline constexpr unsigned seed_count(unsigned full) {
  return kSanitized ? (full + 1) / 2 : full;
}

/// A scene that diverges: symplectic Euler at 20 times its stability limit on a small block.
inline constexpr const char* kDivergingScene = R"({
    "mesh": {"box": {"cells": [2, 2, 2], "size": [0.01, 0.01, 0.01]}},
    "integrator": {"type": "symplectic-euler", "dt": 0.002},
    "fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}], "gravity": [0, 0, -9.81], "frames": 200})";

/// ../shared/data beside the project root (override with INCISE_DATA_DIR).
inline std::filesystem::path data_dir() {
  if (const char* dir = std::getenv("INCISE_DATA_DIR")) {
    return dir;
  }
  return std::filesystem::path(INCISE_SOURCE_DIR) / ".." / "shared" / "data";
}

inline std::filesystem::path data_file(const std::string& relative) {
  return data_dir() / relative;
}

/// A scratch directory for one test, emptied the first time this process asks for it. Named
/// after the running test as well, so tests run in parallel processes never share one.
inline std::filesystem::path scratch_dir(const std::string& name) {
  std::string test_name = "no-test";
  if (const auto* info = ::testing::UnitTest::GetInstance()->current_test_info()) {
    test_name = std::string(info->test_suite_name()) + "." + info->name();
  }
  for (char& c : test_name) {
    c = std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '.' ? c : '_';
  }
  const auto dir =
      std::filesystem::temp_directory_path() / "incise-tests" / (test_name + "-" + name);
  static std::set<std::filesystem::path> emptied;
  if (emptied.insert(dir).second) {
    std::filesystem::remove_all(dir);
  }
  std::filesystem::create_directories(dir);
  return dir;
}

/// `text` with every character that may not appear in a test name replaced by '_'.
inline std::string test_name_from(std::string text) {
  for (char& c : text) {
    c = std::isalnum(static_cast<unsigned char>(c)) != 0 ? c : '_';
  }
  return text;
}

/// The standard tetrahedron (0,0,0), e1, e2, e3 scaled by `size` (m); volume size^3 / 6.
inline TetMesh unit_tet(double size = 1.0) {
  return TetMesh({Vec3(0, 0, 0), Vec3(size, 0, 0), Vec3(0, size, 0), Vec3(0, 0, size)},
                 {Tet{0, 1, 2, 3}});
}

/// A bar 8 x 2 x 2 cm of 8 x 2 x 2 cells.
inline TetMesh bar_8x2x2cm() {
  return make_box_grid({{8, 2, 2}, Vec3(0.08, 0.02, 0.02), Vec3::Zero(), 6});
}

/// The bytes of the file at `path` (empty if it cannot be read).
inline std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

/// The keys a parser lists as valid where it refuses an unknown one: `parse` must throw an
/// InputError whose message says "(valid here: a, b, c)". A failure is added when it throws
/// no such list, or nothing.
template <typename Parse>
std::vector<std::string> keys_listed_as_valid(Parse parse, const std::string& what) {
  try {
    parse();
  } catch (const InputError& error) {
    const std::string message = error.what();
    const std::size_t at = message.find("(valid here: ");
    if (at == std::string::npos) {
      ADD_FAILURE() << "no list of valid keys in: " << message;
      return {};
    }
    std::vector<std::string> keys;
    std::stringstream list(message.substr(at + 13, message.find(')', at) - at - 13));
    for (std::string key; std::getline(list, key, ',');) {
      keys.push_back(key.substr(key.find_first_not_of(' ')));
    }
    return keys;
  }
  ADD_FAILURE() << "an unknown key was accepted: " << what;
  return {};
}

/// Whether a reference text names `key`, as `key` or "key".
inline bool names_key(const std::string& reference, const std::string& key) {
  return reference.find("`" + key + "`") != std::string::npos ||
         reference.find("\"" + key + "\"") != std::string::npos;
}

}  // namespace incise::test
