#pragma once
// Reading CT volumes through ITK (well-kept readers, not hand-written parsers): MetaImage
// `.mhd`/`.mha` by ITK's MetaIO (every element type, both byte orders, `ElementDataFile = LIST`
// and the `name.%d first last step` slice pattern), DICOM files and series folders by GDCM
// (slices sorted by position, rescale slope and intercept applied: Hounsfield units).

#include <filesystem>

#include "incise/imaging/volume_image.hpp"

namespace incise::imaging {

/// Whether this build reads volumes (the INCISE_WITH_ITK option).
[[nodiscard]] bool can_read_volumes();

/// Reads a `.mhd`/`.mha` file, a DICOM file, or a folder holding a DICOM series (the series
/// with the most slices when there are several). Throws InputError naming the file and the
/// fault for anything unreadable, multi-component (colour) voxels, or more than 2^31 voxels
/// (refused from the header, before any allocation).
[[nodiscard]] VolumeImage read_volume(const std::filesystem::path& path);

}  // namespace incise::imaging
