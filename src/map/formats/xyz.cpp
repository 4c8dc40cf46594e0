// XYZ text point clouds: one point per line (docs/map-format.md, "XYZ text").
#include "lmalign/map/formats/xyz.hpp"

#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "lmalign/core/error.hpp"
#include "text_tokens.hpp"

namespace lmalign {

namespace {

using formats_detail::Lines;
using formats_detail::parse_double;
using formats_detail::quoted;

/// Splits a record at blanks, tabs and commas (a comma with blanks around it is one separator).
void split_fields(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  std::size_t i = 0;
  const auto is_separator = [](char c) { return c == ' ' || c == '\t' || c == ','; };
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) break;
    std::size_t end = i;
    while (end < line.size() && !is_separator(line[end])) ++end;
    fields.push_back(line.substr(i, end - i));
    i = end;
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i < line.size() && line[i] == ',') {
      ++i;
      // A trailing comma leaves an empty last field, which is not a number.
      std::size_t rest = i;
      while (rest < line.size() && (line[rest] == ' ' || line[rest] == '\t')) ++rest;
      if (rest >= line.size()) fields.push_back(std::string_view());
    }
  }
}

const char* field_name(std::size_t i) {
  static constexpr const char* kNames[3] = {"x", "y", "z"};
  return i < 3 ? kNames[i] : nullptr;
}

}  // namespace

bool is_xyz_record(const std::string& line) {
  std::vector<std::string_view> fields;
  split_fields(line, fields);
  if (fields.size() < 3) return false;
  double value = 0.0;
  for (const std::string_view f : fields) {
    if (!parse_double(f, value)) return false;
  }
  return true;
}

Map read_xyz_map(std::istream& in, const std::string& name) {
  const std::string text = formats_detail::slurp(in, name);
  Lines lines(text, name);
  Map map;
  map.header.scale = MapScale::kUnknown;  // a bare point cloud does not say
  std::vector<std::string_view> fields;
  std::size_t columns = 0;
  std::size_t first_line = 0;
  std::string_view line;
  while (lines.next_record(line)) {
    split_fields(line, fields);
    if (columns == 0) {
      if (fields.size() < 3) {
        throw ParseError(name, lines.line(),
                         "expected a point 'x y z' (3 or more numbers), got " +
                             std::to_string(fields.size()) + " field(s)");
      }
      columns = fields.size();
      first_line = lines.line();
    } else if (fields.size() != columns) {
      throw ParseError(name, lines.line(),
                       "expected " + std::to_string(columns) + " fields as on line " +
                           std::to_string(first_line) + ", got " + std::to_string(fields.size()));
    }
    Landmark l;
    l.id = static_cast<Id>(map.landmarks.size());
    for (std::size_t i = 0; i < columns; ++i) {
      double value = 0.0;
      if (!parse_double(fields[i], value)) {
        const std::string what = field_name(i) != nullptr
                                     ? std::string("field '") + field_name(i) + "'"
                                     : "field " + std::to_string(i + 1);
        throw ParseError(name, lines.line(),
                         what + " is not a finite number: " + quoted(fields[i]));
      }
      if (i < 3) l.p_world(static_cast<Eigen::Index>(i)) = value;
    }
    l.covariance_unknown = true;
    map.landmarks.push_back(std::move(l));
  }
  return map;
}

Map read_xyz_map(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open XYZ file '" + path + "'");
  return read_xyz_map(in, path);
}

}  // namespace lmalign
