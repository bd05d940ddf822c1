#include "incise/imaging/read_volume.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "incise/core/error.hpp"
#include "isolated_read.hpp"

#ifdef INCISE_HAVE_ITK
#include "itk_headers.hpp"
#endif

namespace incise::imaging {

#ifdef INCISE_HAVE_ITK

namespace {

using ItkVolume = itk::Image<float, 3>;

// More voxels than this are refused from the header: 8 GiB of floats is beyond any CT this
// planner is meant for, and a corrupt header must not drive an allocation.
constexpr double kMaxVoxels = 2147483648.0;

std::string lower_extension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

/// Reads the header, checks what it claims, then the voxels (as float; ITK converts every
/// element type and byte order).
VolumeImage read_with(itk::ImageIOBase* io, const std::vector<std::string>& files,
                      const std::filesystem::path& shown, const std::string& format) {
  io->SetFileName(files.front());
  io->ReadImageInformation();
  const unsigned dimensions = io->GetNumberOfDimensions();
  if (dimensions < 2 || dimensions > 3) {
    throw InputError(
        shown.string(), 0,
        fmt::format("a {}-dimensional image; a CT volume has 3 (or 2 per slice)", dimensions));
  }
  if (io->GetNumberOfComponents() != 1) {
    throw InputError(shown.string(), 0,
                     fmt::format("voxels of {} components (colour?); a CT volume has one scalar "
                                 "value per voxel",
                                 io->GetNumberOfComponents()));
  }
  double claimed = static_cast<double>(files.size());
  for (unsigned d = 0; d < dimensions; ++d) {
    claimed *= static_cast<double>(io->GetDimensions(d));
  }
  if (!(claimed >= 1.0) || claimed > kMaxVoxels) {
    throw InputError(shown.string(), 0,
                     fmt::format("the header claims {:.0f} voxels (at most {:.0f} are read)",
                                 claimed, kMaxVoxels));
  }
  const std::string voxel_type = itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType());

  auto reader = itk::ImageSeriesReader<ItkVolume>::New();
  reader->SetImageIO(io);
  reader->SetFileNames(files);
  reader->Update();
  const ItkVolume* volume = reader->GetOutput();

  VolumeImage image;
  const auto size = volume->GetLargestPossibleRegion().GetSize();
  for (int axis = 0; axis < 3; ++axis) {
    image.size[static_cast<std::size_t>(axis)] = size[static_cast<unsigned>(axis)];
    image.spacing[axis] = volume->GetSpacing()[static_cast<unsigned>(axis)];
    image.origin[axis] = volume->GetOrigin()[static_cast<unsigned>(axis)];
    for (int row = 0; row < 3; ++row) {
      image.direction(row, axis) =
          volume->GetDirection()(static_cast<unsigned>(row), static_cast<unsigned>(axis));
    }
  }
  const float* values = volume->GetBufferPointer();
  image.values.assign(values, values + image.voxel_count());
  image.description = fmt::format("{} ({}), {} x {} x {} voxels", format, voxel_type, image.size[0],
                                  image.size[1], image.size[2]);
  check_volume(image, shown.string());
  return image;
}

/// MetaIO's slice pattern, "name.%03d first last step" (or the name alone: slices 1 to n).
/// Checked here because MetaIO hands the name to sprintf (a %s or %n in it would read or write
/// memory) and divides by a step it derives from a partial list (a crash, found by fuzzing).
void check_slice_pattern(const std::string& data, const std::filesystem::path& header) {
  std::vector<std::string> words;
  for (std::size_t at = 0; at < data.size();) {
    const std::size_t start = data.find_first_not_of(" \t", at);
    if (start == std::string::npos) {
      break;
    }
    const std::size_t end = std::min(data.find_first_of(" \t", start), data.size());
    words.push_back(data.substr(start, end - start));
    at = end;
  }
  const auto fail = [&](const std::string& why) {
    throw InputError(
        header.string(), 0,
        fmt::format("ElementDataFile '{}': {} (expected 'name.%03d first last step')", data, why));
  };
  if (words.empty()) {
    fail("no file name");
  }
  // Exactly one integer conversion (%d, %3d, %03d); any other % must be %%.
  int conversions = 0;
  const std::string& name = words[0];
  for (std::size_t i = 0; i < name.size(); ++i) {
    if (name[i] != '%') {
      continue;
    }
    if (i + 1 < name.size() && name[i + 1] == '%') {
      ++i;
      continue;
    }
    std::size_t j = i + 1;
    while (j < name.size() && j - i <= 3 &&
           std::isdigit(static_cast<unsigned char>(name[j])) != 0) {
      ++j;
    }
    if (j >= name.size() || name[j] != 'd') {
      fail("the slice pattern may hold only an integer field such as %03d");
    }
    ++conversions;
    i = j;
  }
  if (conversions != 1) {
    fail("the slice pattern needs exactly one integer field such as %03d");
  }
  if (words.size() == 1) {
    return;
  }
  if (words.size() != 4) {
    fail("give the first and last slice numbers and the step");
  }
  long long numbers[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    const std::string& word = words[static_cast<std::size_t>(k) + 1];
    std::size_t used = 0;
    try {
      numbers[k] = std::stoll(word, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != word.size() || std::llabs(numbers[k]) > 1000000000LL) {
      fail("'" + word + "' is not a slice number");
    }
  }
  if (numbers[2] == 0 || (numbers[1] - numbers[0]) / numbers[2] < 0) {
    fail("the step must be nonzero and lead from the first slice to the last");
  }
}

/// MetaIO reports raw data shorter than its header claims on stderr only and returns what it
/// read: the sizes are checked here first, for a single raw file and for data inside the header
/// file (LOCAL). Compressed, ASCII, LIST and slice-pattern data are left to MetaIO.
void check_metaimage_data(itk::MetaImageIO* io, const std::filesystem::path& header) {
  io->SetFileName(header.string());
  io->ReadImageInformation();
  const MetaImage* meta = io->GetMetaImagePointer();
  // Only uncompressed binary data has a size known from the header; but a data file that does
  // not exist is refused here whatever the encoding (ITK 5.2's MetaIO leaks a stream when it
  // finds none).
  const bool sized = !meta->CompressedData() && meta->BinaryData();
  double needed = static_cast<double>(io->GetComponentSize());
  for (unsigned d = 0; d < io->GetNumberOfDimensions(); ++d) {
    needed *= static_cast<double>(io->GetDimensions(d));
  }
  const std::string data = meta->ElementDataFileName();
  std::error_code error;
  if (data == "LOCAL") {
    if (!sized) {
      return;
    }
    const auto size = std::filesystem::file_size(header, error);
    if (!error && static_cast<double>(size) < needed) {
      throw InputError(header.string(), 0,
                       fmt::format("holds {} bytes, fewer than the {:.0f} bytes of voxels its "
                                   "header claims",
                                   size, needed));
    }
    return;
  }
  if (data.find('%') != std::string::npos) {
    check_slice_pattern(data, header);
    return;
  }
  if (data.rfind("LIST", 0) == 0) {
    return;
  }
  std::filesystem::path file(data);
  if (file.is_relative()) {
    file = header.parent_path() / file;
  }
  const auto size = std::filesystem::file_size(file, error);
  if (error) {
    throw InputError(header.string(), 0,
                     fmt::format("its data file '{}' cannot be read", file.string()));
  }
  if (sized && static_cast<double>(size) < needed) {
    throw InputError(header.string(), 0,
                     fmt::format("its data file '{}' holds {} bytes, fewer than the {:.0f} bytes "
                                 "of voxels the header claims",
                                 file.string(), size, needed));
  }
}

VolumeImage read_dicom_folder(const std::filesystem::path& folder) {
  auto names = itk::GDCMSeriesFileNames::New();
  names->SetDirectory(folder.string());
  const std::vector<std::string> series = names->GetSeriesUIDs();
  if (series.empty()) {
    throw InputError(folder.string(), 0, "the folder holds no DICOM series");
  }
  // Several series (a scout, a contrast phase): the one with the most slices.
  std::vector<std::string> files;
  for (const std::string& uid : series) {
    std::vector<std::string> candidate = names->GetFileNames(uid);
    if (candidate.size() > files.size()) {
      files = std::move(candidate);
    }
  }
  auto io = itk::GDCMImageIO::New();
  return read_with(io, files, folder,
                   fmt::format("DICOM series of {} slices ({} series in the folder)", files.size(),
                               series.size()));
}

/// ITK reports through exceptions (its warnings would only repeat them on stderr): they become
/// InputErrors naming the file. Running out of memory is reported by read_in_child, which
/// knows the child's memory budget.
template <typename Read>
VolumeImage with_itk_errors(const std::filesystem::path& path, const Read& read) {
  itk::Object::GlobalWarningDisplayOff();
  try {
    return read();
  } catch (const itk::ExceptionObject& failure) {
    throw InputError(path.string(), 0,
                     std::string("cannot read the volume: ") + failure.GetDescription());
  }
}

/// s: how long GDCM may take for a file or series.
constexpr double kReaderSeconds = 300.0;

/// bytes: what the child reading a DICOM file or folder may allocate: 512 MiB, plus 64 bytes
/// for every byte of the files (a voxel of 2 bytes becomes a 4-byte float; ITK, GDCM and the
/// answer to the parent each hold a copy; compressed data expands).
std::size_t dicom_memory_budget(const std::filesystem::path& path) {
  std::uintmax_t bytes = 0;
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) {
    for (const auto& entry : std::filesystem::directory_iterator(path, error)) {
      if (entry.is_regular_file(error)) {
        bytes += entry.file_size(error);
      }
    }
  } else {
    bytes = std::filesystem::file_size(path, error);
  }
  constexpr std::uintmax_t kBase = std::uintmax_t{512} << 20;
  constexpr std::uintmax_t kPerByte = 64;
  const std::uintmax_t most = std::numeric_limits<std::size_t>::max() / 2;
  return static_cast<std::size_t>(std::min(most, kBase + kPerByte * std::min(bytes, most / 128)));
}

VolumeImage read_dicom_file(const std::filesystem::path& path) {
  auto dicom = itk::GDCMImageIO::New();
  if (!dicom->CanReadFile(path.string().c_str())) {
    throw InputError(path.string(), 0,
                     "not a volume incise reads: give a MetaImage (.mhd, .mha), a DICOM file or "
                     "a folder holding a DICOM series");
  }
  return read_with(dicom, {path.string()}, path, "DICOM file");
}

}  // namespace

bool can_read_volumes() {
  return true;
}

VolumeImage read_volume(const std::filesystem::path& path) {
  std::error_code error;
  if (!std::filesystem::exists(path, error)) {
    throw InputError(path.string(), 0, "no such file or folder");
  }
  const std::string extension = lower_extension(path);
  if (!std::filesystem::is_directory(path, error) && (extension == ".mhd" || extension == ".mha")) {
    // ITK 5.2's MetaIO frees memory it does not own on some malformed headers and loops for
    // ever on others (found by fuzzing, fuzz/corpus/metaimage): it reads in a child process
    // too, with a time limit far beyond what a real volume takes.
    return read_in_child(
        [&] {
          return with_itk_errors(path, [&] {
            auto io = itk::MetaImageIO::New();
            check_metaimage_data(io, path);
            return read_with(io, {path.string()}, path, "MetaImage");
          });
        },
        path, "MetaIO (ITK's MetaImage reader)", 60.0);
  }
  // DICOM goes through GDCM, whose assertions abort the process: in a child process. GDCM
  // also allocates what an element's declared length says before it reads the element (1.4 GB
  // for a 1 KB file, found by fuzzing): the child may use at most what a volume stored in
  // these files could need, as floats, several times over (compressed transfer syntaxes
  // included), plus a fixed allowance.
  constexpr const char* kGdcm = "GDCM (the DICOM library ITK reads through)";
  const std::size_t budget = dicom_memory_budget(path);
  if (std::filesystem::is_directory(path, error)) {
    return read_in_child(
        [&] { return with_itk_errors(path, [&] { return read_dicom_folder(path); }); }, path, kGdcm,
        kReaderSeconds, budget);
  }
  return read_in_child([&] { return with_itk_errors(path, [&] { return read_dicom_file(path); }); },
                       path, kGdcm, kReaderSeconds, budget);
}

#else

bool can_read_volumes() {
  return false;
}

VolumeImage read_volume(const std::filesystem::path& path) {
  throw InputError(path.string(), 0,
                   "reading CT volumes needs ITK: rebuild with -DINCISE_WITH_ITK=ON "
                   "(Debian: libinsighttoolkit5-dev), or give the plan 'surfaces'");
}

#endif

}  // namespace incise::imaging
