#include "incise/cut/blade.hpp"

#include <fmt/format.h>

#include <charconv>
#include <fstream>
#include <sstream>

#include "incise/core/atomic_file.hpp"
#include "incise/core/error.hpp"

namespace incise {

std::vector<std::array<Vec3, 3>> swept_triangles(const BladePose& from, const BladePose& to) {
  std::vector<std::array<Vec3, 3>> triangles;
  const std::array<std::array<Vec3, 3>, 2> candidates = {
      {{from.tip, from.base, to.base}, {from.tip, to.base, to.tip}}};
  for (const auto& triangle : candidates) {
    const double area2 = (triangle[1] - triangle[0]).cross(triangle[2] - triangle[0]).norm();
    const double scale = std::max({(triangle[1] - triangle[0]).squaredNorm(),
                                   (triangle[2] - triangle[0]).squaredNorm(),
                                   (triangle[2] - triangle[1]).squaredNorm()});
    if (area2 > 1e-12 * scale) {
      triangles.push_back(triangle);
    }
  }
  return triangles;
}

BladePose blade_in_frame(const ToolFrame& frame, const BladeGeometry& blade) {
  BladePose pose;
  pose.tip = frame.translation;
  pose.base = frame.translation + frame.rotation * (blade.length * blade.axis.normalized());
  return pose;
}

ToolFrame frame_of_blade(const BladePose& pose, const BladeGeometry& blade) {
  ToolFrame frame;
  frame.translation = pose.tip;
  const Vec3 direction = pose.base - pose.tip;
  if (direction.norm() > 0.0 && blade.axis.norm() > 0.0) {
    frame.rotation =
        Eigen::Quaterniond::FromTwoVectors(blade.axis.normalized(), direction.normalized())
            .toRotationMatrix();
  }
  return frame;
}

std::vector<BladePose> read_blade_path(const std::filesystem::path& path) {
  std::ifstream stream(path);
  if (!stream) {
    throw InputError(path.string(), 0, "cannot open the blade path");
  }
  std::string line;
  std::size_t number = 0;
  std::vector<BladePose> poses;
  const std::string header = "t,tip_x,tip_y,tip_z,base_x,base_y,base_z";
  while (std::getline(stream, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') {
      line.pop_back();
    }
    if (line.find_first_not_of(" \t") == std::string::npos) {
      continue;
    }
    if (number == 1 || (poses.empty() && line.rfind("t,", 0) == 0)) {
      std::string compact;
      for (char c : line) {
        if (c != ' ' && c != '\t') {
          compact += c;
        }
      }
      if (compact != header) {
        throw InputError(path.string(), number, "the header must be '" + header + "'");
      }
      continue;
    }
    double values[7];
    std::size_t field = 0;
    std::size_t start = 0;
    while (field < 7) {
      const std::size_t comma = line.find(',', start);
      std::string text =
          line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      text.erase(0, text.find_first_not_of(" \t"));
      text.erase(text.find_last_not_of(" \t") + 1);
      const auto [end, error] =
          std::from_chars(text.data(), text.data() + text.size(), values[field]);
      if (text.empty() || error != std::errc() || end != text.data() + text.size() ||
          !std::isfinite(values[field])) {
        throw InputError(path.string(), number,
                         fmt::format("field {} ('{}') is not a finite number", field + 1, text));
      }
      ++field;
      if (comma == std::string::npos) {
        break;
      }
      start = comma + 1;
      if (field == 7) {
        throw InputError(path.string(), number, "more than 7 fields");
      }
    }
    if (field != 7) {
      throw InputError(path.string(), number, fmt::format("7 fields expected, found {}", field));
    }
    BladePose pose{values[0], Vec3(values[1], values[2], values[3]),
                   Vec3(values[4], values[5], values[6])};
    if (!poses.empty() && pose.time < poses.back().time) {
      throw InputError(path.string(), number, "time goes backwards");
    }
    if ((pose.tip - pose.base).norm() == 0.0) {
      throw InputError(path.string(), number, "the blade has zero length (tip == base)");
    }
    poses.push_back(pose);
  }
  if (number == 0) {
    throw InputError(path.string(), 0, "the blade path is empty");
  }
  if (poses.empty()) {
    throw InputError(path.string(), number, "the blade path has a header but no poses");
  }
  return poses;
}

void write_blade_path(const std::filesystem::path& path, const std::vector<BladePose>& poses) {
  std::string text = "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n";
  for (const BladePose& pose : poses) {
    text += fmt::format("{},{},{},{},{},{},{}\n", pose.time, pose.tip.x(), pose.tip.y(),
                        pose.tip.z(), pose.base.x(), pose.base.y(), pose.base.z());
  }
  write_file_atomically(path, text);
}

}  // namespace incise
