#include "incise/core/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <random>
#include <streambuf>
#include <string>
#include <system_error>

#include "incise/core/error.hpp"

namespace incise {

/// A stream buffer over a POSIX file descriptor. std::filebuf would do the writing, but it
/// forgets errno, and "write failed" without "No space left on device" tells a user nothing.
class AtomicFile::DescriptorBuffer : public std::streambuf {
 public:
  explicit DescriptorBuffer(int descriptor) : descriptor_(descriptor) {
    setp(buffer_.data(), buffer_.data() + buffer_.size());
  }
  DescriptorBuffer(const DescriptorBuffer&) = delete;
  DescriptorBuffer& operator=(const DescriptorBuffer&) = delete;
  ~DescriptorBuffer() override { (void)close(); }

  /// Flushes and closes; false if anything failed since opening (see error()).
  bool close() {
    if (descriptor_ < 0) {
      return error_ == 0;
    }
    (void)flush_buffer();
    if (::close(descriptor_) != 0 && error_ == 0) {
      error_ = errno;
    }
    descriptor_ = -1;
    return error_ == 0;
  }
  [[nodiscard]] int error() const { return error_; }

 protected:
  int_type overflow(int_type character) override {
    if (!flush_buffer()) {
      return traits_type::eof();
    }
    if (!traits_type::eq_int_type(character, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(character);
      pbump(1);
    }
    return traits_type::not_eof(character);
  }
  int sync() override { return flush_buffer() ? 0 : -1; }

 private:
  bool flush_buffer() {
    const char* data = pbase();
    std::size_t left = static_cast<std::size_t>(pptr() - pbase());
    while (left > 0 && error_ == 0) {
      const ssize_t written = ::write(descriptor_, data, left);
      if (written < 0) {
        if (errno != EINTR) {
          error_ = errno;
        }
        continue;
      }
      data += written;
      left -= static_cast<std::size_t>(written);
    }
    setp(buffer_.data(), buffer_.data() + buffer_.size());
    return error_ == 0;
  }

  int descriptor_;
  int error_ = 0;
  std::array<char, 1 << 16> buffer_{};
};

namespace {

std::string reason(int code) {
  return std::generic_category().message(code);
}

std::string hex_suffix() {
  std::random_device entropy;
  constexpr char kDigits[] = "0123456789abcdef";
  std::string suffix = ".tmp";
  unsigned value = entropy();
  for (int i = 0; i < 8; ++i, value >>= 4U) {
    suffix.push_back(kDigits[value & 15U]);
  }
  return suffix;
}

}  // namespace

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)), stream_(nullptr) {
  temporary_ = path_;
  temporary_ += hex_suffix();
  const int descriptor =
      ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);  // NOLINT
  if (descriptor < 0) {
    throw InputError(path_.string(), 0, "cannot open for writing: " + reason(errno));
  }
  buffer_ = std::make_unique<DescriptorBuffer>(descriptor);
  stream_.rdbuf(buffer_.get());
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    buffer_->close();
    std::error_code ignored;
    std::filesystem::remove(temporary_, ignored);
  }
}

void AtomicFile::write(std::string_view bytes) {
  stream_.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

void AtomicFile::commit() {
  stream_.flush();
  const bool stream_good = static_cast<bool>(stream_);
  if (!buffer_->close() || !stream_good) {
    const int code = buffer_->error();
    throw InputError(path_.string(), 0,
                     "write failed (" + (code != 0 ? reason(code) : std::string("stream error")) +
                         "): nothing was written, any earlier file there is unchanged");
  }
  std::error_code error;
  std::filesystem::rename(temporary_, path_, error);
  if (error) {
    throw InputError(path_.string(), 0,
                     "cannot move the written file into place: " + error.message());
  }
  committed_ = true;
}

void write_file_atomically(const std::filesystem::path& path, std::string_view bytes) {
  AtomicFile file(path);
  file.write(bytes);
  file.commit();
}

}  // namespace incise
