// Private helpers of src/experiment/: number formatting that is exact and locale-independent.
#pragma once

#include <charconv>
#include <cmath>
#include <string>

#include "lmalign/core/text.hpp"

namespace lmalign::detail {

using lmalign::shortest;  // core/text.hpp

/// `v` rounded to 1e-9 first (so 0.1 + 2 * 0.1 prints "0.3"), then shortest().
inline std::string shortest_rounded(double v) {
  if (!std::isfinite(v)) return shortest(v);
  return shortest(std::round(v * 1e9) / 1e9);
}

}  // namespace lmalign::detail
