// CT volumes in (MetaImage in every variant the planner meets, DICOM files and series written
// by an independent writer) and isosurfaces out (a sphere-in-sphere phantom, scan borders).

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <queue>
#include <random>
#include <string>
#include <vector>

#include "incise/core/child_process.hpp"
#include "incise/core/error.hpp"
#include "incise/imaging/isosurface.hpp"
#include "incise/imaging/read_volume.hpp"
#include "incise/imaging/trilinear.hpp"

namespace {

using namespace incise;
using namespace incise::imaging;
namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A small volume with a distinct value per voxel: v = i + 10 j + 100 k.
constexpr std::size_t kNx = 6;
constexpr std::size_t kNy = 5;
constexpr std::size_t kNz = 4;
double expected(std::size_t i, std::size_t j, std::size_t k) {
  return static_cast<double>(i + 10 * j + 100 * k);
}

template <typename T>
std::string encode(T value, bool big_endian) {
  std::string bytes(sizeof(T), '\0');
  std::memcpy(bytes.data(), &value, sizeof(T));
  if (big_endian) {
    std::reverse(bytes.begin(), bytes.end());
  }
  return bytes;
}

template <typename T>
std::string slice_bytes(std::size_t k, bool big_endian) {
  std::string bytes;
  for (std::size_t j = 0; j < kNy; ++j) {
    for (std::size_t i = 0; i < kNx; ++i) {
      // Through an integer: uint8 keeps the value modulo 256 (a double beyond 255 would be UB).
      bytes += encode(static_cast<T>(static_cast<long long>(expected(i, j, k))), big_endian);
    }
  }
  return bytes;
}

std::string header(const std::string& type, bool big_endian, const std::string& data_file) {
  return "ObjectType = Image\nNDims = 3\nDimSize = 6 5 4\nElementSpacing = 0.5 0.75 2\n"
         "Offset = -10 20 30.5\nElementType = " +
         type + "\nElementByteOrderMSB = " + (big_endian ? "True" : "False") +
         "\nElementDataFile = " + data_file + "\n";
}

void expect_test_volume(const VolumeImage& image, const std::string& what) {
  ASSERT_EQ(image.size[0], kNx) << what;
  ASSERT_EQ(image.size[1], kNy) << what;
  ASSERT_EQ(image.size[2], kNz) << what;
  EXPECT_NEAR(image.spacing.x(), 0.5, 1e-12) << what;
  EXPECT_NEAR(image.spacing.y(), 0.75, 1e-12) << what;
  EXPECT_NEAR(image.spacing.z(), 2.0, 1e-12) << what;
  EXPECT_NEAR(image.origin.x(), -10.0, 1e-12) << what;
  EXPECT_NEAR(image.origin.z(), 30.5, 1e-12) << what;
  for (std::size_t k = 0; k < kNz; ++k) {
    for (std::size_t j = 0; j < kNy; ++j) {
      for (std::size_t i = 0; i < kNx; ++i) {
        ASSERT_EQ(image.at(i, j, k), expected(i, j, k)) << what << " voxel " << i << j << k;
      }
    }
  }
}

template <typename T>
void write_raw_pair(const fs::path& dir, const std::string& name, const std::string& type,
                    bool big_endian) {
  std::ofstream raw(dir / (name + ".raw"), std::ios::binary);
  for (std::size_t k = 0; k < kNz; ++k) {
    raw << slice_bytes<T>(k, big_endian);
  }
  std::ofstream(dir / (name + ".mhd")) << header(type, big_endian, name + ".raw");
}

TEST(ReadVolume, MetaImageEveryElementTypeAndByteOrder) {
  ASSERT_TRUE(can_read_volumes());
  const fs::path dir = fresh_dir("incise_imaging_types");
  for (bool big : {false, true}) {
    const std::string order = big ? "_msb" : "_lsb";
    write_raw_pair<std::uint8_t>(dir, "u8" + order, "MET_UCHAR", big);
    write_raw_pair<std::uint16_t>(dir, "u16" + order, "MET_USHORT", big);
    write_raw_pair<std::int16_t>(dir, "i16" + order, "MET_SHORT", big);
    write_raw_pair<std::int32_t>(dir, "i32" + order, "MET_INT", big);
    write_raw_pair<float>(dir, "f32" + order, "MET_FLOAT", big);
    write_raw_pair<double>(dir, "f64" + order, "MET_DOUBLE", big);
  }
  // uint8 holds values up to 255 only: the test volume's largest is 345.
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == ".mhd" && !entry.path().stem().string().starts_with("u8")) {
      expect_test_volume(read_volume(entry.path()), entry.path().filename().string());
    }
  }
  const VolumeImage bytes = read_volume(dir / "u8_msb.mhd");
  EXPECT_EQ(
      bytes.at(5, 4, 1),
      static_cast<float>(static_cast<std::uint8_t>(static_cast<long long>(expected(5, 4, 1)))));
  fs::remove_all(dir);
}

TEST(ReadVolume, MetaImageInlineListAndSlicePattern) {
  const fs::path dir = fresh_dir("incise_imaging_layouts");
  // .mha: header and data in one file.
  {
    std::ofstream mha(dir / "inline.mha", std::ios::binary);
    mha << header("MET_SHORT", false, "LOCAL");
    for (std::size_t k = 0; k < kNz; ++k) {
      mha << slice_bytes<std::int16_t>(k, false);
    }
  }
  expect_test_volume(read_volume(dir / "inline.mha"), "inline .mha");
  // One file per slice, listed after the header.
  {
    std::string list = header("MET_USHORT", true, "LIST");
    for (std::size_t k = 0; k < kNz; ++k) {
      const std::string name = "listed_" + std::to_string(k) + ".raw";
      std::ofstream(dir / name, std::ios::binary) << slice_bytes<std::uint16_t>(k, true);
      list += name + "\n";
    }
    std::ofstream(dir / "list.mhd") << list;
  }
  expect_test_volume(read_volume(dir / "list.mhd"), "LIST");
  // The `name.%d first last step` pattern, as the headsq stack is read (slices 1..4 here,
  // numbered 3, 5, 7, 9 with step 2).
  for (std::size_t k = 0; k < kNz; ++k) {
    std::ofstream(dir / ("quarter." + std::to_string(3 + 2 * k)), std::ios::binary)
        << slice_bytes<std::uint16_t>(k, false);
  }
  std::ofstream(dir / "pattern.mhd") << header("MET_USHORT", false, "quarter.%d 3 9 2");
  expect_test_volume(read_volume(dir / "pattern.mhd"), "slice pattern");
  fs::remove_all(dir);
}

std::string read_error(const fs::path& path) {
  try {
    (void)read_volume(path);
  } catch (const InputError& error) {
    return error.what();
  }
  return "";
}

TEST(ReadVolume, BadInputNamesTheFileAndAllocatesNothingItWasNotGiven) {
  const fs::path dir = fresh_dir("incise_imaging_bad");
  EXPECT_NE(read_error(dir / "absent.mhd").find("no such file"), std::string::npos);
  // A header claiming 10^15 voxels is refused before anything is allocated.
  std::ofstream(dir / "huge.mhd") << "ObjectType = Image\nNDims = 3\nDimSize = 100000 100000 "
                                     "100000\nElementType = MET_UCHAR\nElementDataFile = x.raw\n";
  std::ofstream(dir / "x.raw") << "abc";
  const std::string huge = read_error(dir / "huge.mhd");
  EXPECT_NE(huge.find("huge.mhd"), std::string::npos) << huge;
  EXPECT_NE(huge.find("claims"), std::string::npos) << huge;
  // Data shorter than the header says.
  std::ofstream(dir / "short.mhd") << header("MET_FLOAT", false, "short.raw");
  std::ofstream(dir / "short.raw", std::ios::binary) << slice_bytes<float>(0, false);
  const std::string truncated = read_error(dir / "short.mhd");
  EXPECT_NE(truncated.find("short.mhd"), std::string::npos) << truncated;
  // Colour voxels are not a CT.
  std::ofstream(dir / "rgb.mhd") << "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\n"
                                    "ElementNumberOfChannels = 3\nElementType = MET_UCHAR\n"
                                    "ElementDataFile = rgb.raw\n";
  std::ofstream(dir / "rgb.raw", std::ios::binary) << std::string(24, 'x');
  EXPECT_NE(read_error(dir / "rgb.mhd").find("components"), std::string::npos);
  // Slice patterns MetaIO would hand to sprintf or divide by a zero step (found by fuzzing).
  for (const char* pattern : {"slice%s.raw 1 4 1", "slice%d%n.raw 1 4 1", "slice%d.raw 1 4 0",
                              "slice%d.raw 0 0", "slice%d.raw 4 1 1"}) {
    std::ofstream(dir / "pattern.mhd") << header("MET_UCHAR", false, pattern);
    const std::string message = read_error(dir / "pattern.mhd");
    EXPECT_NE(message.find("pattern.mhd"), std::string::npos) << pattern << ": " << message;
    EXPECT_NE(message.find("expected 'name.%03d first last step'"), std::string::npos)
        << pattern << ": " << message;
  }
  // Neither MetaImage nor DICOM.
  std::ofstream(dir / "notes.txt") << "hello";
  EXPECT_NE(read_error(dir / "notes.txt").find("not a volume"), std::string::npos);
  EXPECT_NE(read_error(dir).find("no DICOM series"), std::string::npos);
  fs::remove_all(dir);
}

/// Writes, with pydicom (Debian's python3-pydicom, an independent DICOM writer), pydicom's
/// CT_small.dcm and a 5-slice series made from it: slices 2.5 mm apart, files named in reverse
/// order, slice k's rescale intercept raised by 100 k. False when pydicom is missing.
bool write_dicom_series(const fs::path& dir) {
  const fs::path script = dir / "write_series.py";
  std::ofstream(script) << R"(import copy, os, shutil, sys
from pydicom import dcmread
from pydicom.data import get_testdata_file
out = sys.argv[1]
source = get_testdata_file('CT_small.dcm')
shutil.copy(source, os.path.join(out, 'CT_small.dcm'))
os.makedirs(os.path.join(out, 'series'))
base = dcmread(source)
for k in range(5):
    s = copy.deepcopy(base)
    s.InstanceNumber = k + 1
    position = [float(v) for v in base.ImagePositionPatient]
    position[2] += 2.5 * k
    s.ImagePositionPatient = position
    s.RescaleIntercept = float(base.RescaleIntercept) + 100 * k
    s.SOPInstanceUID = base.SOPInstanceUID + '.%d' % (k + 1)
    s.file_meta.MediaStorageSOPInstanceUID = s.SOPInstanceUID
    s.save_as(os.path.join(out, 'series', 'image%02d.dcm' % (4 - k)))
)";
  const std::string command = "/usr/bin/python3 " + script.string() + " " + dir.string();
  return std::system(command.c_str()) == 0;
}

TEST(ReadVolume, DicomFileAndSeriesSortedByPosition) {
  const fs::path dir = fresh_dir("incise_imaging_dicom");
  if (!write_dicom_series(dir)) {
    GTEST_SKIP() << "python3-pydicom is not installed (scripts/install-deps.sh installs it)";
  }
  const VolumeImage single = read_volume(dir / "CT_small.dcm");
  EXPECT_EQ(single.size[0], 128u);
  EXPECT_EQ(single.size[1], 128u);
  EXPECT_EQ(single.size[2], 1u);
  EXPECT_NEAR(single.spacing.x(), 0.661468, 1e-6);
  EXPECT_NEAR(single.origin.x(), -158.135803, 1e-4);
  EXPECT_NEAR(single.origin.z(), -75.699997, 1e-4);
  const auto [low, high] = value_range(single);
  EXPECT_LT(low, 0.0F) << "rescaled to Hounsfield units (intercept -1024)";
  EXPECT_GT(high, 0.0F);

  const VolumeImage series = read_volume(dir / "series");
  ASSERT_EQ(series.size[2], 5u);
  EXPECT_NEAR(series.spacing.z(), 2.5, 1e-6);
  EXPECT_NEAR(series.origin.z(), -75.699997, 1e-4) << "the lowest slice first";
  for (std::size_t k = 0; k < 5; ++k) {
    for (std::size_t probe : {0u, 777u, 8191u}) {
      const std::size_t i = probe % 128;
      const std::size_t j = probe / 128;
      EXPECT_NEAR(series.at(i, j, k) - single.at(i, j, 0), 100.0 * static_cast<double>(k), 1e-3)
          << "slice " << k;
    }
  }
  fs::remove_all(dir);
}

TEST(ReadVolume, ADicomFileThatStopsGdcmIsRefusedAndTheProcessGoesOn) {
  // pydicom's RT Dose files without Number of Frames make Debian's GDCM fail an assert() and
  // abort (found by fuzzing): GDCM reads in a child process, so this is an error, not a crash.
  const fs::path rtdose =
      "/usr/lib/python3/dist-packages/pydicom/data/test_files/rtdose_1frame.dcm";
  if (!fs::exists(rtdose)) {
    GTEST_SKIP() << "python3-pydicom is not installed (scripts/install-deps.sh installs it)";
  }
  const std::string message = read_error(rtdose);
  EXPECT_NE(message.find(rtdose.string()), std::string::npos) << message;
  EXPECT_NE(message.find("GDCM"), std::string::npos) << message;
  EXPECT_NE(message.find("assertion"), std::string::npos) << message;
  // And the next file reads as ever in the same process.
  const fs::path dir = fresh_dir("incise_imaging_after_abort");
  if (write_dicom_series(dir)) {
    EXPECT_EQ(read_volume(dir / "CT_small.dcm").size[0], 128u);
  }
  fs::remove_all(dir);
}

TEST(ReadVolume, ADicomHeaderClaimingGigabytesIsRefusedWithoutTakingThem) {
  // Found by fuzzing: 439 bytes whose file meta group declares an element of 1.4 GB. GDCM
  // allocates (and zero-fills) what an element's length says before reading it; the child
  // that reads DICOM may only use what files of this size can need, so the allocation fails
  // there and the file is refused, naming it.
  if (!child_memory_budget_applies()) {
    GTEST_SKIP() << "sanitizer build: the child's address space is not limited";
  }
  const fs::path file = fs::path(INCISE_SOURCE_DIR) / "tests/data/dicom/claims_1400mb.dcm";
  const std::string message = read_error(file);
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  rusage usage{};
  ASSERT_EQ(getrusage(RUSAGE_CHILDREN, &usage), 0);
  EXPECT_LT(usage.ru_maxrss, 400L * 1024) << "KiB: the child's largest resident size";
}

/// A sphere-in-sphere phantom (mm): soft tissue to radius 40, bone to radius 25, about
/// (50, 50, 50); values ramp linearly across one voxel at each interface, as partial volumes do.
VolumeImage phantom(double spacing) {
  VolumeImage image;
  const auto n = static_cast<std::size_t>(std::lround(100.0 / spacing)) + 1;
  image.size = {n, n, n};
  image.spacing = Vec3::Constant(spacing);
  image.origin = Vec3(-50.0, -50.0, -50.0);
  image.values.resize(n * n * n);
  auto ramp = [&](double t) { return std::clamp(t / spacing + 0.5, 0.0, 1.0); };
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t j = 0; j < n; ++j) {
      for (std::size_t i = 0; i < n; ++i) {
        const double r = (spacing * Vec3(static_cast<double>(i), static_cast<double>(j),
                                         static_cast<double>(k)) -
                          Vec3::Constant(50.0))
                             .norm();
        image.values[i + n * (j + n * k)] =
            static_cast<float>(500.0 * ramp(40.0 - r) + 700.0 * ramp(25.0 - r));
      }
    }
  }
  return image;
}

std::size_t border_edges(const SurfaceMesh& surface) {
  std::map<std::pair<int, int>, int> uses;
  for (const Triangle& t : surface.triangles) {
    for (int e = 0; e < 3; ++e) {
      const int a = static_cast<int>(t[static_cast<std::size_t>(e)]);
      const int b = static_cast<int>(t[static_cast<std::size_t>((e + 1) % 3)]);
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  }
  std::size_t border = 0;
  for (const auto& [edge, count] : uses) {
    border += count == 1 ? 1 : 0;
  }
  return border;
}

TEST(Isosurface, PhantomRadiiWithinHalfAVoxel) {
  for (double spacing : {2.0, 3.0}) {
    const VolumeImage image = phantom(spacing);
    for (const auto& [iso, radius] : {std::pair{250.0, 40.0}, std::pair{850.0, 25.0}}) {
      const Isosurface found = extract_isosurface(image, iso, {}, "phantom");
      ASSERT_GT(found.surface.triangles.size(), 100u);
      EXPECT_EQ(found.border_triangles, 0u);
      EXPECT_EQ(border_edges(found.surface), 0u) << "a closed surface";
      double mean = 0.0;
      double worst = 0.0;
      for (const Vec3& p : found.surface.points) {
        // The phantom's centre is the patient-space origin.
        const double error = p.norm() - radius;
        mean += error / static_cast<double>(found.surface.points.size());
        worst = std::max(worst, std::abs(error));
      }
      EXPECT_LT(worst, 0.5 * spacing) << "iso " << iso << ", spacing " << spacing;
      EXPECT_LT(std::abs(mean), 0.1 * spacing) << "iso " << iso << ", spacing " << spacing;
    }
  }
}

TEST(Isosurface, TissueLeavingTheScanLeavesTheSurfaceOpen) {
  // A cylinder along k through the whole volume: its ends are the scan's border, not skin.
  VolumeImage image;
  image.size = {21, 21, 15};
  image.spacing = Vec3(2.0, 2.0, 3.0);
  image.values.resize(image.voxel_count());
  for (std::size_t k = 0; k < 15; ++k) {
    for (std::size_t j = 0; j < 21; ++j) {
      for (std::size_t i = 0; i < 21; ++i) {
        const double rho =
            std::hypot(2.0 * static_cast<double>(i) - 20.0, 2.0 * static_cast<double>(j) - 20.0);
        image.values[i + 21 * (j + 21 * k)] =
            static_cast<float>(1000.0 * std::clamp((12.0 - rho) / 2.0 + 0.5, 0.0, 1.0));
      }
    }
  }
  const Isosurface open = extract_isosurface(image, 500.0, {}, "cylinder");
  EXPECT_GT(open.border_triangles, 0u);
  EXPECT_GT(border_edges(open.surface), 0u);
  // Only the side is left: away from the ends (by a triangle, 3 mm) every point is on it.
  for (const Vec3& p : open.surface.points) {
    EXPECT_GT(p.z(), -3.0);
    EXPECT_LT(p.z(), 45.0);
    if (p.z() > 3.0 && p.z() < 39.0) {
      EXPECT_NEAR(std::hypot(p.x() - 20.0, p.y() - 20.0), 12.0, 1.0);
    }
  }
  IsosurfaceOptions closed_options;
  closed_options.open_at_scan_border = false;
  const Isosurface closed = extract_isosurface(image, 500.0, closed_options, "cylinder");
  EXPECT_EQ(closed.border_triangles, 0u);
  EXPECT_EQ(border_edges(closed.surface), 0u);
  // No voxel above the iso value: a clear error naming what was asked.
  try {
    (void)extract_isosurface(image, 5000.0, {}, "plan.json: plan key 'iso.bone'");
    ADD_FAILURE() << "an empty isosurface was accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("iso.bone"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("0 to 1000"), std::string::npos) << error.what();
  }
}

/// Values uniform in [0, 1) voxel by voxel: at an iso value near the percolation threshold,
/// regions that wind, branch and enclose.
VolumeImage random_blobs(const std::array<std::size_t, 3>& size, const Vec3& spacing,
                         std::uint32_t seed) {
  VolumeImage image;
  image.size = size;
  image.spacing = spacing;
  image.values.resize(size[0] * size[1] * size[2]);
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> uniform(0.0F, 1.0F);
  for (float& v : image.values) {
    v = uniform(random);
  }
  return image;
}

/// The voxels at most `iso` that reach the border through such voxels, found voxel by voxel
/// (breadth first): the reference for outside_of, which joins runs.
std::vector<std::uint8_t> outside_by_flood_fill(const VolumeImage& image, double iso) {
  const std::size_t nx = image.size[0];  // (clang 14 cannot capture a structured binding)
  const std::size_t ny = image.size[1];
  const std::size_t nz = image.size[2];
  std::vector<std::uint8_t> outside(image.values.size(), 0);
  std::queue<std::array<std::size_t, 3>> queue;
  auto reach = [&](std::size_t i, std::size_t j, std::size_t k) {
    const std::size_t v = i + nx * (j + ny * k);
    if (outside[v] == 0 && image.values[v] <= iso) {
      outside[v] = 1;
      queue.push({i, j, k});
    }
  };
  for (std::size_t k = 0; k < nz; ++k) {
    for (std::size_t j = 0; j < ny; ++j) {
      for (std::size_t i = 0; i < nx; ++i) {
        if (i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1) {
          reach(i, j, k);
        }
      }
    }
  }
  while (!queue.empty()) {
    const auto [i, j, k] = queue.front();
    queue.pop();
    if (i > 0) {
      reach(i - 1, j, k);
    }
    if (i + 1 < nx) {
      reach(i + 1, j, k);
    }
    if (j > 0) {
      reach(i, j - 1, k);
    }
    if (j + 1 < ny) {
      reach(i, j + 1, k);
    }
    if (k > 0) {
      reach(i, j, k - 1);
    }
    if (k + 1 < nz) {
      reach(i, j, k + 1);
    }
  }
  return outside;
}

TEST(Trilinear, OutsideIsWhatReachesTheScanBorderAndCavitiesAreEnclosed) {
  // Random blobs at the percolation threshold: regions that wind, branch and enclose, and
  // some only reach the border along a long path.
  for (const std::uint32_t seed : {1U, 2U, 3U}) {
    const VolumeImage image = random_blobs({37, 29, 23}, Vec3(1.0, 1.5, 2.0), seed);
    for (const double iso : {0.3, 0.69, 0.75}) {
      const std::vector<std::uint8_t> expected = outside_by_flood_fill(image, iso);
      const std::vector<std::uint8_t> found = outside_of(image, iso);
      ASSERT_EQ(found.size(), expected.size());
      std::size_t enclosed = 0;
      for (std::size_t v = 0; v < found.size(); ++v) {
        ASSERT_EQ(found[v], expected[v]) << "voxel " << v << ", seed " << seed << ", iso " << iso;
        enclosed += image.values[v] <= iso && found[v] == 0 ? 1 : 0;
      }
      if (iso > 0.5) {
        EXPECT_GT(enclosed, 0u) << "the case has enclosed voxels";
      }
    }
  }
  // The sphere-in-sphere phantom with a hollow bone: the marrow (inside radius 15) is enclosed,
  // and the crossings on its wall say so; those on the bone's outer wall do not.
  VolumeImage image = phantom(2.0);
  const auto n = image.size[0];
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t j = 0; j < n; ++j) {
      for (std::size_t i = 0; i < n; ++i) {
        const double r =
            (2.0 * Vec3(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)) -
             Vec3::Constant(50.0))
                .norm();
        if (r < 15.0) {
          image.values[i + n * (j + n * k)] = 500.0F;
        }
      }
    }
  }
  const std::vector<std::uint8_t> outside = outside_of(image, 1000.0);
  const IsoCrossings crossings = iso_crossings(image, 1000.0, 1000000, 0, &outside);
  ASSERT_EQ(crossings.enclosed.size(), crossings.points.size());
  std::size_t inner = 0;
  std::size_t outer = 0;
  for (std::size_t c = 0; c < crossings.points.size(); ++c) {
    const double r = (crossings.points[c] - Vec3::Constant(50.0)).norm();
    EXPECT_EQ(crossings.enclosed[c], r < 20.0 ? 1 : 0) << "r " << r;
    (r < 20.0 ? inner : outer) += 1;
  }
  EXPECT_GT(inner, 100u);
  EXPECT_GT(outer, 100u);
}

/// Per voxel above iso: the number of voxels of its 6-connected region (0 elsewhere), by a
/// breadth-first search: the independent answer small_regions_above is checked against.
std::vector<std::size_t> region_sizes_by_search(const VolumeImage& image, double iso) {
  const std::size_t nx = image.size[0];
  const std::size_t ny = image.size[1];
  const std::size_t nz = image.size[2];
  std::vector<std::size_t> size(image.values.size(), 0);
  std::vector<std::uint8_t> seen(image.values.size(), 0);
  for (std::size_t start = 0; start < image.values.size(); ++start) {
    if (seen[start] != 0 || !(image.values[start] > iso)) {
      continue;
    }
    std::vector<std::size_t> region{start};
    seen[start] = 1;
    for (std::size_t next = 0; next < region.size(); ++next) {
      const std::size_t v = region[next];
      const std::size_t i = v % nx;
      const std::size_t j = (v / nx) % ny;
      const std::size_t k = v / (nx * ny);
      const auto visit = [&](std::size_t w) {
        if (seen[w] == 0 && image.values[w] > iso) {
          seen[w] = 1;
          region.push_back(w);
        }
      };
      if (i > 0)
        visit(v - 1);
      if (i + 1 < nx)
        visit(v + 1);
      if (j > 0)
        visit(v - nx);
      if (j + 1 < ny)
        visit(v + nx);
      if (k > 0)
        visit(v - nx * ny);
      if (k + 1 < nz)
        visit(v + nx * ny);
    }
    for (const std::size_t v : region) {
      size[v] = region.size();
    }
  }
  return size;
}

TEST(Trilinear, SmallRegionsAboveIsoAreTheSpecksAModelCannotHold) {
  // Random blobs: many small regions above iso, some large winding ones.
  for (const std::uint32_t seed : {4U, 5U}) {
    const VolumeImage image = random_blobs({31, 27, 19}, Vec3(1.0, 1.0, 2.0), seed);
    for (const double iso : {0.6, 0.75, 0.85}) {
      const std::vector<std::size_t> sizes = region_sizes_by_search(image, iso);
      for (const std::size_t least : {2UL, 5UL, 40UL}) {
        const std::vector<std::uint8_t> small = small_regions_above(image, iso, least);
        ASSERT_EQ(small.size(), sizes.size());
        std::size_t marked = 0;
        for (std::size_t v = 0; v < small.size(); ++v) {
          const bool expected = sizes[v] > 0 && sizes[v] < least;
          ASSERT_EQ(small[v] != 0, expected)
              << "voxel " << v << " (region of " << sizes[v] << "), seed " << seed << ", iso "
              << iso << ", least " << least;
          marked += small[v];
        }
        if (least == 40) {
          EXPECT_GT(marked, 0U) << "the case has small regions";
        }
      }
    }
  }
  // A speck beside the phantom's bone: the crossings around it say so, the bone's do not.
  VolumeImage image = phantom(2.0);
  const auto n = image.size[0];
  image.values[2 + n * (25 + n * 25)] = 3000.0F;  // one voxel at (4, 50, 50) mm, in soft tissue
  const std::vector<std::uint8_t> outside = outside_of(image, 1000.0);
  const std::vector<std::uint8_t> small = small_regions_above(image, 1000.0, 10);
  const IsoCrossings crossings = iso_crossings(image, 1000.0, 1000000, 0, &outside, &small);
  ASSERT_EQ(crossings.on_small_region.size(), crossings.points.size());
  std::size_t on_speck = 0;
  for (std::size_t c = 0; c < crossings.points.size(); ++c) {
    const bool near_speck = (crossings.points[c] - Vec3(4.0, 50.0, 50.0)).norm() < 2.5;
    EXPECT_EQ(crossings.on_small_region[c] != 0, near_speck) << crossings.points[c].transpose();
    on_speck += near_speck ? 1 : 0;
  }
  EXPECT_EQ(on_speck, 6U);  // the six edges out of the voxel
}

TEST(Trilinear, IsoCrossingsAreEveryEdgeThatCrossesVoxelByVoxel) {
  // Rows of 37 and 13 voxels: not whole words of the scan's eight, so the row's last voxels
  // and the missing +x edge at its end are exercised.
  for (const std::array<std::size_t, 3>& size :
       {std::array<std::size_t, 3>{37, 29, 23}, std::array<std::size_t, 3>{13, 5, 4}}) {
    const VolumeImage image = random_blobs(size, Vec3(1.0, 1.5, 2.0), 9);
    const double iso = 0.7;
    const std::size_t nx = size[0];
    const std::size_t ny = size[1];
    const std::size_t nz = size[2];
    std::vector<Vec3> expected;  // voxel by voxel, then axis: the order iso_crossings keeps
    for (std::size_t k = 0; k < nz; ++k) {
      for (std::size_t j = 0; j < ny; ++j) {
        for (std::size_t i = 0; i < nx; ++i) {
          const double a = image.at(i, j, k);
          const std::array<std::array<std::size_t, 3>, 3> next{
              {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}}};
          for (std::size_t axis = 0; axis < 3; ++axis) {
            const auto [ni, nj, nk] = next[axis];
            if (ni >= nx || nj >= ny || nk >= nz) {
              continue;
            }
            const double b = image.at(ni, nj, nk);
            if ((a > iso) == (b > iso)) {
              continue;
            }
            Vec3 p(static_cast<double>(i), static_cast<double>(j) * 1.5,
                   static_cast<double>(k) * 2.0);
            p[static_cast<Eigen::Index>(axis)] +=
                (iso - a) / (b - a) * image.spacing[static_cast<Eigen::Index>(axis)];
            expected.push_back(p);
          }
        }
      }
    }
    const IsoCrossings all = iso_crossings(image, iso, expected.size() + 1);
    EXPECT_EQ(all.total, expected.size());
    ASSERT_EQ(all.points.size(), expected.size());
    for (std::size_t c = 0; c < expected.size(); ++c) {
      ASSERT_EQ(all.points[c], expected[c]) << "crossing " << c << " of " << expected.size();
    }
    // A sample: about the number wanted, every one a crossing, repeatable for its seed.
    const std::size_t wanted = expected.size() / 4;
    const IsoCrossings sample = iso_crossings(image, iso, wanted, 3);
    EXPECT_EQ(sample.total, expected.size());
    EXPECT_NEAR(static_cast<double>(sample.points.size()), static_cast<double>(wanted),
                4.0 * std::sqrt(static_cast<double>(wanted)) + 2.0);
    for (const Vec3& p : sample.points) {
      EXPECT_NE(std::find(expected.begin(), expected.end(), p), expected.end());
    }
    EXPECT_EQ(iso_crossings(image, iso, wanted, 3).points, sample.points);
  }
}

TEST(Isosurface, DirectionAndOriginPlaceThePointsInPatientSpace) {
  VolumeImage image = phantom(3.0);
  image.origin = Vec3(100.0, -20.0, 7.0);
  // The grid's i axis along patient y, j along -x, k along z.
  image.direction << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const Isosurface found = extract_isosurface(image, 250.0, {}, "turned phantom");
  // The phantom's centre, grid position (50, 50, 50) mm, now lies at origin + R (50, 50, 50).
  const Vec3 centre = image.origin + image.direction * Vec3::Constant(50.0);
  for (const Vec3& p : found.surface.points) {
    EXPECT_NEAR((p - centre).norm(), 40.0, 1.5);
  }
}

}  // namespace
