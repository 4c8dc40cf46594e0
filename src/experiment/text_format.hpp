// Private helpers of src/experiment/: number formatting that is exact and locale-independent.
#pragma once

#include <charconv>
#include <cmath>
#include <string>

namespace lmalign::detail {

/// The shortest decimal text that reads back to exactly `v` ("0.57", "22.5", "1e-05");
/// "inf" / "-inf" / "nan" for non-finite values. Independent of the C locale.
inline std::string shortest(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == 0.0) return "0";  // also for -0.0
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// `v` rounded to 1e-9 first (so 0.1 + 2 * 0.1 prints "0.3"), then shortest().
inline std::string shortest_rounded(double v) {
  if (!std::isfinite(v)) return shortest(v);
  return shortest(std::round(v * 1e9) / 1e9);
}

}  // namespace lmalign::detail
