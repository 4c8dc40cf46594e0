// Text helpers every reader and writer shares: exact, locale-independent numbers and
// whitespace-separated tokens.
#pragma once

#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace lmalign {

/// The shortest decimal text that reads back to exactly `v` ("0.57", "22.5", "1e-05");
/// "inf" / "-inf" / "nan" for non-finite values, "0" for -0.0. Independent of the C locale
/// (std::to_chars).
inline std::string shortest(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == 0.0) return "0";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// The whitespace-separated tokens of one line, in order.
inline std::vector<std::string> split_whitespace(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream ss(line);
  std::string tok;
  while (ss >> tok) out.push_back(tok);
  return out;
}

}  // namespace lmalign
