// PLY landmark maps (include/lmalign/map/formats/ply.hpp; docs/map-format.md "PLY").
#include "lmalign/map/formats/ply.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/io/atomic_file.hpp"
#include "text_tokens.hpp"

namespace lmalign {

namespace {

using formats_detail::Bytes;
using formats_detail::Lines;
using formats_detail::quoted;
using formats_detail::TokenReader;

enum class Scalar { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<Scalar> scalar_of(std::string_view name) {
  struct Entry {
    const char* name;
    Scalar type;
  };
  static constexpr Entry kTypes[] = {
      {"char", Scalar::kInt8},      {"int8", Scalar::kInt8},       {"uchar", Scalar::kUint8},
      {"uint8", Scalar::kUint8},    {"short", Scalar::kInt16},     {"int16", Scalar::kInt16},
      {"ushort", Scalar::kUint16},  {"uint16", Scalar::kUint16},   {"int", Scalar::kInt32},
      {"int32", Scalar::kInt32},    {"uint", Scalar::kUint32},     {"uint32", Scalar::kUint32},
      {"float", Scalar::kFloat32},  {"float32", Scalar::kFloat32}, {"double", Scalar::kFloat64},
      {"float64", Scalar::kFloat64}};
  for (const Entry& e : kTypes) {
    if (name == e.name) return e.type;
  }
  return std::nullopt;
}

std::size_t size_of(Scalar type) {
  switch (type) {
    case Scalar::kInt8:
    case Scalar::kUint8:
      return 1;
    case Scalar::kInt16:
    case Scalar::kUint16:
      return 2;
    case Scalar::kInt32:
    case Scalar::kUint32:
    case Scalar::kFloat32:
      return 4;
    default:
      return 8;
  }
}

struct Property {
  std::string name;
  Scalar type = Scalar::kFloat64;
  bool is_list = false;
  Scalar count_type = Scalar::kUint8;
};

struct Element {
  std::size_t line = 0;  // header line that declares it
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

double read_binary_scalar(Bytes& b, Scalar type, const std::string& what) {
  switch (type) {
    case Scalar::kInt8:
      return b.read<std::int8_t>(what);
    case Scalar::kUint8:
      return b.read<std::uint8_t>(what);
    case Scalar::kInt16:
      return b.read<std::int16_t>(what);
    case Scalar::kUint16:
      return b.read<std::uint16_t>(what);
    case Scalar::kInt32:
      return b.read<std::int32_t>(what);
    case Scalar::kUint32:
      return b.read<std::uint32_t>(what);
    case Scalar::kFloat32: {
      const float v = b.read<float>(what);
      return static_cast<double>(v);  // checked for finiteness by the caller
    }
    default:
      return b.read<double>(what);
  }
}

constexpr const char* kCovNames[6] = {"cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"};

// Where each wanted vertex property is (index into the element's properties), -1 if absent.
struct VertexLayout {
  int xyz[3] = {-1, -1, -1};
  int cov[6] = {-1, -1, -1, -1, -1, -1};
  int covariance_known = -1;
  bool has_covariance = false;
};

}  // namespace

Map read_ply_map(std::istream& in, const std::string& name) {
  const std::string text = formats_detail::slurp(in, name);
  // ---- header
  Lines lines(text, name);
  auto next_line = [&lines](std::string_view& line) { return lines.next_raw(line); };
  std::string_view line;
  if (!next_line(line) || line != "ply") {
    throw ParseError(name, 1, "expected 'ply' as the first line (not a PLY file)");
  }
  bool binary = false;
  bool have_format = false;
  MapHeader header;
  header.scale = MapScale::kUnknown;  // unless our obj_info says
  std::vector<Element> elements;
  for (;;) {
    if (!next_line(line))
      throw ParseError(name, lines.line(), "file ends inside the header (no end_header)");
    TokenReader t(line, name, lines.line());
    const std::string_view keyword = t.next();
    if (keyword == "end_header") break;
    if (keyword == "obj_info") {
      // Our own metadata (write_ply_map); other tools' obj_info lines are skipped.
      const std::string_view key = t.next();
      if (key == "lmalign_scale") {
        const std::string_view value = t.next();
        const std::optional<MapScale> scale = map_scale_from_name(std::string(value));
        if (!scale) {
          t.fail("obj_info lmalign_scale " + quoted(value) +
                 " is not one of metric, arbitrary, unknown");
        }
        header.scale = *scale;
      } else if (key == "lmalign_covariance") {
        const std::string_view value = t.next();
        if (value != "estimated" && value != "assumed") {
          t.fail("obj_info lmalign_covariance " + quoted(value) +
                 " is not one of estimated, assumed");
        }
        header.covariance_assumed = value == "assumed";
      } else {
        continue;
      }
      if (!t.at_end()) t.fail("unexpected field after the obj_info value");
      continue;
    }
    if (keyword == "comment" || keyword.empty()) continue;
    if (keyword == "format") {
      const std::string_view format = t.next();
      if (format == "ascii") {
        binary = false;
      } else if (format == "binary_little_endian") {
        binary = true;
      } else {
        t.fail("format " + quoted(format) +
               " is not supported (expected ascii or binary_little_endian)");
      }
      if (t.next() != "1.0") t.fail("expected format version 1.0");
      have_format = true;
    } else if (keyword == "element") {
      Element e;
      e.line = lines.line();
      e.name = std::string(t.next());
      if (e.name.empty()) t.fail("expected 'element NAME COUNT'");
      const long long count = t.integer("element count", 0, std::numeric_limits<long long>::max());
      e.count = static_cast<std::uint64_t>(count);
      elements.push_back(std::move(e));
    } else if (keyword == "property") {
      if (elements.empty()) t.fail("property before any element");
      Property p;
      std::string_view type = t.next();
      if (type == "list") {
        p.is_list = true;
        const std::optional<Scalar> count_type = scalar_of(t.next());
        if (!count_type || *count_type == Scalar::kFloat32 || *count_type == Scalar::kFloat64) {
          t.fail("expected an integer count type in 'property list COUNT_TYPE TYPE NAME'");
        }
        p.count_type = *count_type;
        type = t.next();
      }
      const std::optional<Scalar> scalar = scalar_of(type);
      if (!scalar) t.fail("unknown property type " + quoted(type));
      p.type = *scalar;
      p.name = std::string(t.next());
      if (p.name.empty()) t.fail("expected a property name");
      // A repeated name would make the covariance count ambiguous (found by fuzz_ply_reader).
      for (const Property& other : elements.back().properties) {
        if (other.name == p.name) {
          t.fail("duplicate property '" + p.name + "' in element '" + elements.back().name + "'");
        }
      }
      elements.back().properties.push_back(std::move(p));
    } else {
      t.fail("unknown header keyword " + quoted(keyword));
    }
    if (!t.at_end()) t.fail("unexpected field in the header line");
  }
  if (!have_format) throw ParseError(name, lines.line(), "the header has no 'format' line");
  std::size_t vertex_index = elements.size();
  for (std::size_t i = 0; i < elements.size(); ++i) {
    if (elements[i].name == "vertex") {
      vertex_index = i;
      break;
    }
  }
  if (vertex_index == elements.size()) {
    throw ParseError(name, lines.line(), "the header declares no 'vertex' element");
  }
  const Element& vertex = elements[vertex_index];
  VertexLayout layout;
  int num_cov = 0;
  for (std::size_t i = 0; i < vertex.properties.size(); ++i) {
    const Property& p = vertex.properties[i];
    if (p.is_list) {
      throw ParseError(name, lines.line(),
                       "vertex property '" + p.name + "' is a list (not supported)");
    }
    for (int k = 0; k < 3; ++k) {
      if (p.name == std::string(1, "xyz"[k])) layout.xyz[k] = static_cast<int>(i);
    }
    for (int k = 0; k < 6; ++k) {
      if (p.name == kCovNames[k]) {
        layout.cov[k] = static_cast<int>(i);
        ++num_cov;
      }
    }
    if (p.name == "covariance_known") layout.covariance_known = static_cast<int>(i);
  }
  for (int k = 0; k < 3; ++k) {
    if (layout.xyz[k] < 0) {
      throw ParseError(name, lines.line(),
                       std::string("the vertex element has no '") + "xyz"[k] + "' property");
    }
  }
  if (num_cov != 0 && num_cov != 6) {
    throw ParseError(name, lines.line(),
                     "the vertex element has " + std::to_string(num_cov) +
                         " of the 6 covariance properties cov_xx cov_xy cov_xz cov_yy cov_yz "
                         "cov_zz (all or none)");
  }
  layout.has_covariance = num_cov == 6;

  // ---- body
  const std::size_t pos = lines.offset();
  const std::string_view body = std::string_view(text).substr(pos);
  Bytes bytes(body, name, pos);
  TokenReader tokens(body, name, lines.line() + 1);
  const auto body_offset = pos;
  Map map;
  map.header = header;
  std::vector<double> values;
  for (std::size_t e = 0; e <= vertex_index; ++e) {
    const Element& element = elements[e];
    // An element without properties occupies no bytes, whatever its count: nothing to read (a
    // count of 1e14 once made the loop below run for hours; found by fuzz_ply_reader).
    if (element.properties.empty()) continue;
    // Smallest size of one instance: each property its size (binary) or one byte (ASCII).
    std::size_t min_bytes = 0;
    for (const Property& p : element.properties) {
      min_bytes += binary ? (p.is_list ? size_of(p.count_type) : size_of(p.type)) : 1;
    }
    const std::size_t remaining = binary ? bytes.remaining() : tokens.remaining_bytes();
    if (min_bytes > 0 && element.count > remaining / min_bytes) {
      throw ParseError(name, element.line,
                       "element '" + element.name + "' count " + std::to_string(element.count) +
                           " cannot fit in the " + std::to_string(remaining) +
                           " bytes left for it (at least " + std::to_string(min_bytes) +
                           " each; truncated?)");
    }
    if (e == vertex_index) map.landmarks.reserve(element.count);
    for (std::uint64_t i = 0; i < element.count; ++i) {
      values.assign(element.properties.size(), 0.0);
      for (std::size_t k = 0; k < element.properties.size(); ++k) {
        const Property& p = element.properties[k];
        const std::string what = element.name + " " + std::to_string(i) + " " + p.name;
        if (p.is_list) {
          const double n = binary ? read_binary_scalar(bytes, p.count_type, what + " count")
                                  : static_cast<double>(tokens.integer(
                                        what + " count", 0, std::numeric_limits<int>::max()));
          if (!(n >= 0.0) ||
              n > static_cast<double>(binary ? bytes.remaining() : tokens.remaining_bytes())) {
            if (binary) bytes.fail(what + " count " + std::to_string(n) + " is out of range");
            tokens.fail(what + " count is out of range");
          }
          for (std::size_t j = 0; j < static_cast<std::size_t>(n); ++j) {
            if (binary) {
              read_binary_scalar(bytes, p.type, what);
            } else {
              tokens.number(what);
            }
          }
          continue;
        }
        if (binary) {
          const std::size_t at = bytes.offset();
          values[k] = read_binary_scalar(bytes, p.type, what);
          if (!std::isfinite(values[k])) bytes.fail_at(at, what + " is not finite");
        } else {
          values[k] = tokens.number(what);
        }
      }
      if (e != vertex_index) continue;
      const std::size_t where_line = tokens.line();
      const std::size_t where_byte = body_offset + bytes.offset();
      auto fail = [&](const std::string& detail) {
        if (binary) throw ParseError(name, 0, "byte " + std::to_string(where_byte) + ": " + detail);
        throw ParseError(name, where_line, detail);
      };
      Landmark landmark;
      landmark.id = static_cast<Id>(i);
      for (int k = 0; k < 3; ++k)
        landmark.p_world(k) = values[static_cast<std::size_t>(layout.xyz[k])];
      landmark.covariance_unknown = !layout.has_covariance;
      if (layout.has_covariance) {
        const auto c = [&](int k) { return values[static_cast<std::size_t>(layout.cov[k])]; };
        landmark.cov_world_m2 << c(0), c(1), c(2), c(1), c(3), c(4), c(2), c(4), c(5);
        const Eigen::SelfAdjointEigenSolver<Mat3> eig(landmark.cov_world_m2,
                                                      Eigen::EigenvaluesOnly);
        const double largest = eig.eigenvalues().cwiseAbs().maxCoeff();
        if (eig.info() != Eigen::Success || !std::isfinite(largest) ||
            eig.eigenvalues()(0) < -1e-9 * std::max(1e-12, largest)) {
          fail("vertex " + std::to_string(i) +
               ": covariance is not positive semi-definite (smallest eigenvalue " +
               std::to_string(eig.eigenvalues()(0)) + ")");
        }
      }
      if (layout.covariance_known >= 0 &&
          values[static_cast<std::size_t>(layout.covariance_known)] == 0.0) {
        landmark.covariance_unknown = true;
        landmark.cov_world_m2 = Mat3::Zero();
      }
      map.landmarks.push_back(std::move(landmark));
    }
  }
  return map;
}

Map read_ply_map(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open PLY file '" + path + "'");
  return read_ply_map(in, path);
}

void write_ply_map(const std::string& path, const Map& map) {
  write_file_atomically(path, [&map](std::ostream& out) {
    out << "ply\nformat ascii 1.0\ncomment lmalign landmark map (docs/map-format.md)\n"
        << "obj_info lmalign_scale " << map_scale_name(map.header.scale) << "\n"
        << "obj_info lmalign_covariance "
        << (map.header.covariance_assumed ? "assumed" : "estimated") << "\n"
        << "element vertex " << map.landmarks.size() << "\n"
        << "property double x\nproperty double y\nproperty double z\n"
        << "property int num_observations\n";
    for (const char* c : kCovNames) out << "property double " << c << "\n";
    out << "property uchar covariance_known\nend_header\n";
    std::string line;
    char buffer[32];
    auto append = [&](double v) {
      const auto r = std::to_chars(buffer, buffer + sizeof(buffer), v);
      line.append(buffer, r.ptr);
      line.push_back(' ');
    };
    for (const Landmark& l : map.landmarks) {
      line.clear();
      for (int k = 0; k < 3; ++k) append(l.p_world(k));
      line += std::to_string(l.observations.size()) + " ";
      const Mat3& c = l.covariance_unknown ? Mat3::Zero().eval() : l.cov_world_m2;
      for (const double v : {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)}) append(v);
      line += l.covariance_unknown ? "0\n" : "1\n";
      out << line;
    }
  });
}

}  // namespace lmalign
