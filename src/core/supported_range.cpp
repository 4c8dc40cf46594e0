#include "lmalign/core/supported_range.hpp"

#include <cmath>

#include "lmalign/core/error.hpp"

namespace lmalign {

bool within_supported_range(const Vec3& p) {
  // Negated comparisons: NaN is never within.
  return std::abs(p.x()) <= kMaxCoordinateM && std::abs(p.y()) <= kMaxCoordinateM &&
         std::abs(p.z()) <= kMaxCoordinateM;
}

std::vector<std::size_t> beyond_supported_range(const Points3& points) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!within_supported_range(points[i])) out.push_back(i);
  }
  return out;
}

void check_supported_translation(const std::string& what, const Vec3& t_m) {
  if (within_supported_range(t_m)) return;
  throw InvalidArgument(what + ": translation (" + message_number(t_m.x()) + ", " +
                        message_number(t_m.y()) + ", " + message_number(t_m.z()) +
                        ") m is beyond the supported range (|coordinate| <= " +
                        message_number(kMaxCoordinateM) + " m)");
}

void check_supported_magnitude(const std::string& what, double value, double bound,
                               const std::string& unit) {
  if (std::abs(value) <= bound) return;
  throw InvalidArgument(what + ": " + message_number(value) + " " + unit +
                        " is beyond the supported range (|value| <= " + message_number(bound) +
                        " " + unit + ")");
}

void check_supported_sigma(const std::string& what, double value, double min, double max,
                           const std::string& unit) {
  if (value >= min && value <= max) return;
  throw InvalidArgument(what + ": " + message_number(value) + " " + unit +
                        " is outside the supported range of a standard deviation ([" +
                        message_number(min) + ", " + message_number(max) + "] " + unit + ")");
}

std::string left_out_message(std::size_t source_left_out, std::size_t target_left_out) {
  if (source_left_out == 0 && target_left_out == 0) return {};
  auto count = [](std::size_t n, const char* side) {
    return std::to_string(n) + " " + side + (n == 1 ? " landmark" : " landmarks");
  };
  std::string what;
  if (source_left_out > 0) what = count(source_left_out, "source");
  if (target_left_out > 0) {
    if (!what.empty()) what += " and ";
    what += count(target_left_out, "target");
  }
  return what + " beyond the supported range (|coordinate| > " + message_number(kMaxCoordinateM) +
         " m) left out";
}

}  // namespace lmalign
