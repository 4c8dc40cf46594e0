// Exceptions thrown by lmalign. The library never prints; it throws one of these.
#pragma once

#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace lmalign {

/// Base class of every exception lmalign throws on purpose.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

/// A bad argument or option value. The message names the offending field.
class InvalidArgument : public Error {
 public:
  explicit InvalidArgument(const std::string& message) : Error(message) {}
};

/// A file could not be opened, read, or written (message names the path and the OS reason).
class IoError : public Error {
 public:
  explicit IoError(const std::string& message) : Error(message) {}
};

/// A malformed input file. what() reads "<file>:<line>: <what was expected>".
/// line is 1-based; 0 means the problem concerns the file as a whole.
class ParseError : public Error {
 public:
  ParseError(std::string file, std::size_t line, std::string detail)
      : Error(format(file, line, detail)),
        file_(std::move(file)),
        line_(line),
        detail_(std::move(detail)) {}

  const std::string& file() const { return file_; }
  std::size_t line() const { return line_; }
  /// The message without the "<file>:<line>: " prefix.
  const std::string& detail() const { return detail_; }

 private:
  static std::string format(const std::string& file, std::size_t line, const std::string& detail) {
    return line > 0 ? file + ":" + std::to_string(line) + ": " + detail : file + ": " + detail;
  }
  std::string file_;
  std::size_t line_;
  std::string detail_;
};

/// A number as error messages show it: printf's %g (six significant digits, "inf", "nan").
inline std::string message_number(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

}  // namespace lmalign
