#include "incise/core/error.hpp"

namespace incise {
namespace {
std::string located(const std::string& file, std::size_t line, const std::string& message) {
  std::string where = file;
  if (line > 0) {
    where += ":" + std::to_string(line);
  }
  return where.empty() ? message : where + ": " + message;
}
}  // namespace

InputError::InputError(std::string file, std::size_t line, const std::string& message)
    : Error(located(file, line, message)), file_(std::move(file)), line_(line) {}

InputError::InputError(const std::string& message) : Error(message) {}

}  // namespace incise
