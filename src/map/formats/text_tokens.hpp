// Whitespace-separated tokens of a whole text file, with line numbers, for the strict readers
// of other formats (private to src/map/formats).
#pragma once

#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <istream>
#include <iterator>
#include <string>
#include <string_view>
#include <system_error>

#include "lmalign/core/error.hpp"

namespace lmalign::formats_detail {

/// A token quoted for an error message: at most 32 bytes, control bytes as \xHH.
inline std::string quoted(std::string_view token) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out = "'";
  for (std::size_t i = 0; i < token.size() && i < 32; ++i) {
    const auto byte = static_cast<unsigned char>(token[i]);
    if (byte < 0x20 || byte >= 0x7f) {
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    } else {
      out += token[i];
    }
  }
  if (token.size() > 32) out += "...";
  return out + "'";
}

/// Reads the whole stream; throws IoError naming `name` on a read error.
inline std::string slurp(std::istream& in, const std::string& name) {
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw IoError("cannot read '" + name + "'");
  return text;
}

/// Strict parse of a whole token as a finite double (std::from_chars syntax).
inline bool parse_double(std::string_view token, double& value) {
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end && std::isfinite(value);
}

/// Strict parse of a whole token as a decimal integer.
inline bool parse_integer(std::string_view token, long long& value) {
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end;
}

class TokenReader {
 public:
  TokenReader(std::string_view text, std::string name, std::size_t first_line = 1)
      : text_(text), name_(std::move(name)), line_(first_line), token_line_(first_line) {}

  /// The next token, or an empty view at the end of the text. Counts newlines.
  std::string_view next() {
    skip_space();
    token_line_ = line_;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }

  /// Lets number() and integer() accept one trailing ',' on a token (COLMAP text files written
  /// with ", " between fields, which COLMAP's own reader accepts).
  void allow_trailing_comma(bool allow) { trailing_comma_ = allow; }

  /// A finite number named `what`; ParseError otherwise.
  double number(const std::string& what) {
    const std::string_view token = require_value(what);
    double value = 0.0;
    if (!parse_double(token, value)) fail(what + " is not a finite number: " + quoted(token));
    return value;
  }

  /// An integer in [min, max] named `what`; ParseError otherwise.
  long long integer(const std::string& what, long long min, long long max) {
    const std::string_view token = require_value(what);
    long long value = 0;
    if (!parse_integer(token, value) || value < min || value > max) {
      fail(what + " is not an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
           "]: " + quoted(token));
    }
    return value;
  }

  /// True if only whitespace remains.
  bool at_end() {
    skip_space();
    token_line_ = line_;
    return pos_ >= text_.size();
  }
  std::size_t remaining_bytes() const { return text_.size() - pos_; }
  /// Line of the last token read (1-based).
  std::size_t line() const { return token_line_; }
  const std::string& name() const { return name_; }

  [[noreturn]] void fail(const std::string& detail) const {
    throw ParseError(name_, token_line_, detail);
  }

 private:
  static bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
  }
  void skip_space() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  std::string_view require(const std::string& what) {
    const std::string_view token = next();
    if (token.empty()) fail("file ends where " + what + " was expected (truncated?)");
    return token;
  }

  std::string_view require_value(const std::string& what) {
    std::string_view token = require(what);
    if (trailing_comma_ && token.size() > 1 && token.back() == ',') token.remove_suffix(1);
    return token;
  }

  std::string_view text_;
  std::string name_;
  std::size_t pos_ = 0;
  std::size_t line_ = 1;
  std::size_t token_line_ = 1;
  bool trailing_comma_ = false;
};

/// The lines of a whole text, numbered from 1, without their '\n' and one trailing '\r'.
class Lines {
 public:
  Lines(std::string_view text, std::string name) : text_(text), name_(std::move(name)) {}
  /// The next raw line (without '\n' and one '\r'), false at the end.
  bool next_raw(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const std::size_t eol = text_.find('\n', pos_);
    const std::size_t end = eol == std::string::npos ? text_.size() : eol;
    line = text_.substr(pos_, end - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = eol == std::string::npos ? text_.size() : eol + 1;
    ++line_;
    return true;
  }
  /// The next line that is not blank or a comment.
  bool next_record(std::string_view& line) {
    while (next_raw(line)) {
      const std::size_t start = line.find_first_not_of(" \t");
      if (start != std::string_view::npos && line[start] != '#') return true;
    }
    return false;
  }
  std::size_t line() const { return line_; }
  /// Offset of the first byte not yet returned.
  std::size_t offset() const { return pos_; }
  const std::string& name() const { return name_; }

 private:
  std::string_view text_;
  std::string name_;
  std::size_t pos_ = 0;
  std::size_t line_ = 0;
};

/// Little-endian binary fields of a whole file, with byte offsets in the errors:
/// ParseError(name, 0, "byte N: ...").
class Bytes {
 public:
  /// `base`: the file offset of text[0], for the messages.
  Bytes(std::string_view text, std::string name, std::size_t base = 0)
      : text_(text), name_(std::move(name)), base_(base) {}
  template <typename T>
  T read(const std::string& what) {
    if (text_.size() - pos_ < sizeof(T)) {
      fail("file ends where " + what + " (" + std::to_string(sizeof(T)) +
           " bytes) was expected (truncated?)");
    }
    T value;
    std::memcpy(&value, text_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  double number(const std::string& what) {
    const std::size_t at = pos_;
    const double v = read<double>(what);
    if (!std::isfinite(v)) fail_at(at, what + " is not finite");
    return v;
  }
  /// A count of records of at least `min_record_bytes` each; refused if the rest of the file
  /// cannot hold them.
  std::uint64_t count(const std::string& what, std::size_t min_record_bytes) {
    const std::size_t at = pos_;
    const auto n = read<std::uint64_t>(what);
    if (n > remaining() / min_record_bytes) {
      fail_at(at, what + " " + std::to_string(n) + " cannot fit in the " +
                      std::to_string(remaining()) + " bytes that follow (at least " +
                      std::to_string(min_record_bytes) + " bytes each)");
    }
    return n;
  }
  std::string name_string(const std::string& what) {
    const std::size_t nul = text_.find('\0', pos_);
    if (nul == std::string::npos) fail("file ends inside " + what + " (no terminating NUL)");
    std::string s(text_.substr(pos_, nul - pos_));
    pos_ = nul + 1;
    return s;
  }
  std::size_t remaining() const { return text_.size() - pos_; }
  std::size_t offset() const { return pos_; }
  [[noreturn]] void fail(const std::string& detail) const { fail_at(pos_, detail); }
  [[noreturn]] void fail_at(std::size_t at, const std::string& detail) const {
    throw ParseError(name_, 0, "byte " + std::to_string(base_ + at) + ": " + detail);
  }
  void expect_end() const {
    if (remaining() != 0)
      fail(std::to_string(remaining()) + " unexpected bytes after the last record");
  }

 private:
  std::string_view text_;
  std::string name_;
  std::size_t base_ = 0;
  std::size_t pos_ = 0;
};

}  // namespace lmalign::formats_detail
