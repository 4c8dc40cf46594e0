// Pinhole intrinsics: parsing and validation (method.md §1).
#include "lmalign/map/camera.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

}  // namespace

PinholeIntrinsics PinholeIntrinsics::parse(const std::string& text) {
  const std::string expected =
      "expected 4 comma-separated numbers fx,fy,cx,cy in pixels (e.g. 517.3,516.5,318.6,255.3)";
  std::vector<double> values;
  std::string::size_type start = 0;
  while (true) {
    const auto comma = text.find(',', start);
    const std::string token =
        trim(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (token.empty()) {
      throw InvalidArgument("intrinsics \"" + text + "\": empty value; " + expected);
    }
    errno = 0;
    char* end = nullptr;
    const double value = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0' || errno == ERANGE) {
      throw InvalidArgument("intrinsics \"" + text + "\": \"" + token + "\" is not a number; " +
                            expected);
    }
    values.push_back(value);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (values.size() != 4) {
    throw InvalidArgument("intrinsics \"" + text + "\": got " + std::to_string(values.size()) +
                          " values; " + expected);
  }
  PinholeIntrinsics k{values[0], values[1], values[2], values[3]};
  std::string why;
  if (!k.is_valid(&why)) throw InvalidArgument("intrinsics \"" + text + "\": " + why);
  return k;
}

bool PinholeIntrinsics::is_valid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  auto str = [](double v) {
    std::ostringstream os;
    os << v;
    return os.str();
  };
  if (!std::isfinite(fx_px) || fx_px <= 0.0) {
    return fail("fx_px (" + str(fx_px) + ") must be finite and > 0");
  }
  if (!std::isfinite(fy_px) || fy_px <= 0.0) {
    return fail("fy_px (" + str(fy_px) + ") must be finite and > 0");
  }
  if (!std::isfinite(cx_px)) return fail("cx_px (" + str(cx_px) + ") must be finite");
  if (!std::isfinite(cy_px)) return fail("cy_px (" + str(cy_px) + ") must be finite");
  return true;
}

}  // namespace lmalign
