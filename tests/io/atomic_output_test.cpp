// Nothing lost on failure: a write that fails (an unwritable folder, a disk that fills up,
// an error half-way) leaves no truncated file and leaves the file that was there unchanged.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <fstream>
#include <sstream>

#include "incise/core/atomic_file.hpp"
#include "incise/core/error.hpp"
#include "incise/io/mesh_io.hpp"
#include "incise/mesh/generators.hpp"
#include "io_test_support.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

TetMesh box(int cells) {
  BoxGridOptions options;
  options.cells = {cells, cells, cells};
  return make_box_grid(options);
}

std::size_t files_in(const std::filesystem::path& folder) {
  std::size_t count = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(folder)) {
    ++count;
  }
  return count;
}

/// Files larger than `bytes` cannot be written while this lives (the kernel's per-process
/// file size limit, which binds root too): what a full disk looks like to a writer.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    previous_handler_ = signal(SIGXFSZ, SIG_IGN);  // EFBIG instead of a killed process
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &limit);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    signal(SIGXFSZ, previous_handler_);
  }

 private:
  rlimit saved_{};
  sighandler_t previous_handler_ = nullptr;
};

TEST(AtomicOutput, AnUnwritableFolderIsNamedWithTheReason) {
  const auto dir = test::scratch_dir("atomic-folder");
  test::write_file(dir / "plain-file", "x");
  const auto path = dir / "plain-file" / "out.vtu";
  try {
    write_vtu(path, box(1));
    FAIL() << "no error";
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
    EXPECT_NE(message.find("Not a directory"), std::string::npos) << message;
  }
}

TEST(AtomicOutput, AFullDiskLeavesTheEarlierFileWholeAndNoLeftovers) {
  const auto dir = test::scratch_dir("atomic-full");
  const auto path = dir / "mesh.vtu";
  const TetMesh small = box(1);
  write_vtu(path, small);
  const std::string before = test::file_bytes(path);
  ASSERT_GT(before.size(), 100U);
  const TetMesh large = box(20);  // about 2 MB of .vtu
  {
    const FileSizeLimit limit(64 * 1024);
    try {
      write_vtu(path, large);
      FAIL() << "a 2 MB file was written under a 64 KB limit";
    } catch (const InputError& error) {
      const std::string message = error.what();
      EXPECT_NE(message.find(path.string()), std::string::npos) << message;
      EXPECT_NE(message.find("File too large"), std::string::npos) << message;
    }
  }
  EXPECT_EQ(test::file_bytes(path), before) << "the earlier file was damaged";
  EXPECT_EQ(files_in(dir), 1U) << "a temporary file was left behind";
  // With room again the same write succeeds and reads back.
  write_vtu(path, large);
  EXPECT_EQ(read_tet_mesh(path).mesh.tet_count(), large.tet_count());
}

TEST(AtomicOutput, AWriteAbandonedHalfWayChangesNothing) {
  const auto dir = test::scratch_dir("atomic-abandon");
  const auto path = dir / "report.json";
  write_file_atomically(path, "{\"old\": true}\n");
  {
    AtomicFile file(path);
    file.write("{\"new\": ");  // an exception here would unwind without commit()
  }
  EXPECT_EQ(test::file_bytes(path), "{\"old\": true}\n");
  EXPECT_EQ(files_in(dir), 1U);
}

}  // namespace
}  // namespace incise
