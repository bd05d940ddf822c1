#include "incise/core/error.hpp"

namespace incise {
namespace {
std::string located(const std::string& file, std::size_t line, const std::string& message) {
  if (file.empty()) {
    return message;
  }
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on chained operator+.
  std::string where;
  where.reserve(file.size() + message.size() + 24);
  where.append(file);
  if (line > 0) {
    where.append(":").append(std::to_string(line));
  }
  where.append(": ").append(message);
  return where;
}
}  // namespace

InputError::InputError(std::string file, std::size_t line, const std::string& message)
    : Error(located(file, line, message)), file_(std::move(file)), line_(line) {}

InputError::InputError(const std::string& message) : Error(message) {}

}  // namespace incise
