#include "lmalign/io/ply.hpp"

#include <charconv>
#include <ostream>

#include "lmalign/core/error.hpp"
#include "lmalign/io/output_file.hpp"

namespace lmalign {

void write_ply(const std::string& path, const Points3& points,
               const std::vector<std::array<std::uint8_t, 3>>& rgb) {
  if (!rgb.empty() && rgb.size() != points.size()) {
    throw InvalidArgument("write_ply: " + std::to_string(rgb.size()) + " colours for " +
                          std::to_string(points.size()) + " points");
  }
  write_output(path, [&](std::ostream& out) {
    out << "ply\nformat ascii 1.0\ncomment lmalign point cloud, metres\n"
        << "element vertex " << points.size() << "\n"
        << "property double x\nproperty double y\nproperty double z\n";
    if (!rgb.empty()) out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out << "end_header\n";
    char buf[32];
    for (std::size_t i = 0; i < points.size(); ++i) {
      for (int d = 0; d < 3; ++d) {
        auto r = std::to_chars(buf, buf + sizeof(buf), points[i][d]);
        out << (d ? " " : "") << std::string_view(buf, static_cast<std::size_t>(r.ptr - buf));
      }
      if (!rgb.empty()) {
        out << ' ' << int(rgb[i][0]) << ' ' << int(rgb[i][1]) << ' ' << int(rgb[i][2]);
      }
      out << '\n';
    }
  });
}

}  // namespace lmalign
