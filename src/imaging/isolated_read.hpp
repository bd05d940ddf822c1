#pragma once
// A volume read in a child process: GDCM (Debian's build, through ITK) stops the whole
// process with assert() on some valid DICOM files (an RT Dose without Number of Frames, found
// by fuzzing) and on malformed ones, and an abort cannot be caught. The child reads and sends
// the volume back through a pipe; if it dies, the file is refused with a clear error and
// incise goes on. The same is done for TetGen (src/meshing/tetrahedralize.cpp).

#include <cstddef>
#include <filesystem>
#include <functional>

#include "incise/imaging/volume_image.hpp"

namespace incise::imaging {

/// Runs `read` in a forked child and returns its volume. An InputError it throws is thrown
/// here unchanged; any other exception, a crash or an abort in the child, or no answer within
/// `timeout_seconds`, is an InputError naming `shown` and `library`. `memory_budget` (bytes,
/// 0: none) bounds the child's allocations (run_in_child): a reader that asks for more, as
/// GDCM does for a small file whose header claims gigabytes, fails in the child with
/// std::bad_alloc, reported here as an InputError.
[[nodiscard]] VolumeImage read_in_child(const std::function<VolumeImage()>& read,
                                        const std::filesystem::path& shown, const char* library,
                                        double timeout_seconds = 300.0,
                                        std::size_t memory_budget = 0);

}  // namespace incise::imaging
