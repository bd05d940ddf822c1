#pragma once
// Errors thrown by incise. Bad input always names where it came from (file and line,
// or element id) so a user can find and fix it.

#include <cstddef>
#include <stdexcept>
#include <string>

namespace incise {

/// Base class of every error incise reports.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Malformed or unusable input: a file, a scene, a command-line value.
class InputError : public Error {
 public:
  /// `line` is 1-based; 0 means "no line" (binary data or whole-file problems).
  InputError(std::string file, std::size_t line, const std::string& message);
  /// An error about no file in particular.
  explicit InputError(const std::string& message);

  /// The file it names ("" when none).
  [[nodiscard]] const std::string& file() const { return file_; }
  /// The 1-based line it names (0: none).
  [[nodiscard]] std::size_t line() const { return line_; }

 private:
  std::string file_;
  std::size_t line_ = 0;
};

/// An internal invariant was violated: a bug in incise, never the user's fault.
class InternalError : public Error {
 public:
  using Error::Error;
};

}  // namespace incise

/// Checks an internal invariant in every build type (cheap checks only); throws InternalError.
#define INCISE_ASSERT(condition, message)                                                      \
  do {                                                                                         \
    if (!(condition)) {                                                                        \
      throw ::incise::InternalError(std::string("internal invariant violated: ") + (message) + \
                                    " [" #condition "] at " + __FILE__ + ":" +                 \
                                    std::to_string(__LINE__));                                 \
    }                                                                                          \
  } while (false)
