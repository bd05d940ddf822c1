#pragma once
// Output that is whole or absent: written to a temporary file beside the target and renamed
// over it only once complete, so a killed run, a full disk or a failed conversion never
// leaves a truncated file (nor destroys the file that was there). Every failure names the
// path and the system's reason.

#include <filesystem>
#include <memory>
#include <ostream>
#include <string_view>

namespace incise {

/// A file written whole or not at all: bytes go to a temporary beside the target, renamed
/// over it by commit(), so a reader never sees half a file and a failed write loses nothing.
class AtomicFile {
 public:
  /// Opens a temporary beside `path`; throws InputError naming `path` if it cannot.
  explicit AtomicFile(std::filesystem::path path);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  /// Removes the temporary if commit() was never reached: the old file stays as it was.
  ~AtomicFile();

  /// The temporary's stream, for formatted writes.
  std::ostream& stream() { return stream_; }
  /// Appends bytes to the temporary.
  void write(std::string_view bytes);
  /// Flushes and renames into place; throws InputError (disk full, file too large, rename
  /// refused) and leaves the target untouched.
  void commit();

 private:
  class DescriptorBuffer;  // keeps the system's reason for the first failed write

  std::filesystem::path path_;
  std::filesystem::path temporary_;
  std::unique_ptr<DescriptorBuffer> buffer_;
  std::ostream stream_;
  bool committed_ = false;
};

/// Writes a whole file or nothing (AtomicFile in one call).
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

}  // namespace incise
