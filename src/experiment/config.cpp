// Strict YAML reading of experiment configs (docs/experiments.md, "Config"). Every error names
// the file, the 1-based line (yaml-cpp's mark) and the key path: "paper.yaml:12:
// experiments[1].yaw_deg: expected a list of numbers".
//
// The schema is one table (config_schema.cpp): one row per key (where it is written, which
// experiment types take it, the member it fills, its default, bound, unit and doc). The rows
// give each mapping its known keys, read and check every scalar value, and write the resolved
// config; docs/settings.md prints them. Only what is not one scalar (paths, lists, poses,
// strategies, settings) is read here by code of its own.
#include "lmalign/experiment/config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "config_schema.hpp"
#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "text_format.hpp"

namespace lmalign {

// ----------------------------------------------------------------------------- small types

Isometry3 Pose6::transform() const {
  return pose_from_xyz_rpy_deg(x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg);
}

std::string Quadrant::name() const {
  return std::string(sign_x > 0 ? "+X" : "-X") + (sign_y > 0 ? "+Y" : "-Y");
}

bool Quadrant::parse(const std::string& text, Quadrant* out) {
  for (const Quadrant& q : all()) {
    if (q.name() == text) {
      *out = q;
      return true;
    }
  }
  return false;
}

std::vector<Quadrant> Quadrant::all() { return {{1, 1}, {-1, 1}, {-1, -1}, {1, -1}}; }

std::string to_string(ExperimentType type) { return name_of(detail::kExperimentTypeNames, type); }
std::string to_string(YawPivot pivot) { return name_of(detail::kYawPivotNames, pivot); }
std::string to_string(TranslationDirections d) { return name_of(detail::kDirectionNames, d); }

ScaleMode ExperimentConfig::scale_of(const std::string& strategy) const {
  for (const auto& [name, mode] : strategy_scales) {
    if (name == strategy) return mode;
  }
  return scale;
}

namespace {

namespace fs = std::filesystem;
using namespace detail;

std::string join(const std::vector<std::string>& items, const std::string& sep = ", ") {
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) s += (i ? sep : "") + items[i];
  return s;
}

/// "a, b or c".
std::string join_or(const std::vector<std::string>& items) {
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) {
    s += (i == 0 ? "" : (i + 1 == items.size() ? " or " : ", ")) + items[i];
  }
  return s;
}

// ----------------------------------------------------------------------------- the parser

class Parser {
 public:
  Parser(std::string file, std::string base_dir, const ConfigLoadOptions& options)
      : file_(std::move(file)), base_dir_(std::move(base_dir)), options_(options) {}

  static std::size_t line_of(const YAML::Node& n) {
    if (!n.IsDefined()) return 0;
    const YAML::Mark m = n.Mark();
    return m.is_null() ? 0 : static_cast<std::size_t>(m.line) + 1;
  }

  [[noreturn]] void fail(const YAML::Node& n, const std::string& where,
                         const std::string& what) const {
    throw ParseError(file_, line_of(n), where.empty() ? what : where + ": " + what);
  }
  [[noreturn]] void fail_line(std::size_t line, const std::string& where,
                              const std::string& what) const {
    throw ParseError(file_, line, where.empty() ? what : where + ": " + what);
  }

  /// A mapping with the keys of a schema section: rejects anything else, unknown keys (naming
  /// the nearest known one) and duplicates.
  class MapView {
   public:
    MapView(const Parser& p, const YAML::Node& node, std::string where,
            const std::vector<std::string>& allowed, const std::string& context = "")
        : p_(p), node_(node), where_(std::move(where)) {
      if (!node.IsMap()) p.fail(node, where_, "expected a mapping of " + join(allowed));
      for (auto it = node.begin(); it != node.end(); ++it) {
        const YAML::Node key = it->first;
        if (!key.IsScalar()) p.fail(key, where_, "expected scalar keys");
        const std::string k = key.Scalar();
        if (std::find(allowed.begin(), allowed.end(), k) == allowed.end()) {
          const std::string near = nearest_name(k, allowed);
          p.fail(key, where_,
                 "unknown key '" + k + "'" + context + " (expected one of: " + join(allowed) +
                     (near.empty() ? "" : "; nearest: '" + near + "'") + ")");
        }
        if (fields_.count(k) != 0) {
          p.fail(key, where_,
                 "duplicate key '" + k + "' (first at line " +
                     std::to_string(line_of(fields_.at(k).first)) + ")");
        }
        fields_.emplace(k, std::make_pair(key, it->second));
      }
    }
    bool has(const std::string& key) const { return fields_.count(key) != 0; }
    const YAML::Node& get(const std::string& key) const { return fields_.at(key).second; }
    const YAML::Node& key_node(const std::string& key) const { return fields_.at(key).first; }
    std::string path(const std::string& key) const {
      return where_.empty() ? key : where_ + "." + key;
    }
    const YAML::Node& node() const { return node_; }
    void require(const std::string& key, const std::string& what) const {
      if (!has(key)) p_.fail(node_, where_, "missing key '" + key + "' (" + what + ")");
    }

   private:
    const Parser& p_;
    YAML::Node node_;
    std::string where_;
    std::map<std::string, std::pair<YAML::Node, YAML::Node>> fields_;
  };

  // --- scalars

  std::string scalar(const YAML::Node& n, const std::string& where,
                     const std::string& expected) const {
    if (!n.IsScalar()) fail(n, where, "expected " + expected);
    return n.Scalar();
  }

  double number(const YAML::Node& n, const std::string& where, bool allow_inf = false) const {
    const std::string expected = allow_inf ? "a number (or inf)" : "a finite number";
    std::string s = scalar(n, where, expected);
    std::string lower = s;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower == "inf" || lower == ".inf" || lower == "+inf" || lower == "+.inf" ||
        lower == "infinity") {
      if (!allow_inf) fail(n, where, "expected a finite number, got '" + s + "'");
      return std::numeric_limits<double>::infinity();
    }
    const char* begin = s.data();
    const char* end = s.data() + s.size();
    if (begin != end && *begin == '+') ++begin;
    double v = 0.0;
    const auto r = std::from_chars(begin, end, v);
    if (s.empty() || r.ec != std::errc() || r.ptr != end || !std::isfinite(v)) {
      fail(n, where, "expected " + expected + ", got '" + s + "'");
    }
    return v;
  }

  long long integer(const YAML::Node& n, const std::string& where, long long lo,
                    long long hi) const {
    const std::string range =
        "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    const std::string s = scalar(n, where, range);
    long long v = 0;
    const char* begin = s.data();
    const char* end = s.data() + s.size();
    if (begin != end && *begin == '+') ++begin;
    const auto r = std::from_chars(begin, end, v);
    if (s.empty() || r.ec != std::errc() || r.ptr != end) {
      fail(n, where, "expected " + range + ", got '" + s + "'");
    }
    if (v < lo || v > hi) fail(n, where, "expected " + range + ", got " + s);
    return v;
  }

  std::uint64_t seed(const YAML::Node& n, const std::string& where) const {
    const std::string s = scalar(n, where, "a non-negative integer seed");
    std::uint64_t v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || r.ec != std::errc() || r.ptr != s.data() + s.size()) {
      fail(n, where, "expected a non-negative integer seed (< 2^64), got '" + s + "'");
    }
    return v;
  }

  bool boolean(const YAML::Node& n, const std::string& where) const {
    const std::string s = scalar(n, where, "true or false");
    if (s == "true") return true;
    if (s == "false") return false;
    fail(n, where, "expected true or false, got '" + s + "'");
  }

  /// One of `names`: "expected a, b or c, got 'd'".
  std::string name(const YAML::Node& n, const std::string& where,
                   const std::vector<std::string>& names) const {
    const std::string s = scalar(n, where, join_or(names));
    if (std::find(names.begin(), names.end(), s) == names.end()) {
      fail(n, where, "expected " + join_or(names) + ", got '" + s + "'");
    }
    return s;
  }

  /// A real within a row's bound: "must be > 0, got -1" for a positive value, "expected a number
  /// in [0, 180] degrees, got 190" for an interval.
  double real(const YAML::Node& n, const std::string& where, const Row& row) const {
    const SettingBound& b = row.bound;
    const double v = number(n, where, b.allow_inf);
    if (b.lo == 0.0 && b.lo_open && std::isinf(b.hi)) {
      if (!(v > 0.0)) fail(n, where, "must be > 0, got " + shortest(v));
    } else if (std::isfinite(b.lo) || std::isfinite(b.hi)) {
      if (!(v >= b.lo && v <= b.hi)) {
        fail(n, where,
             "expected a number in [" + shortest(b.lo) + ", " + shortest(b.hi) + "]" +
                 unit_word(row.unit) + ", got " + shortest(v));
      }
    }
    return v;
  }

  /// The value of a scalar row, read and checked against its bound.
  SettingValue value(const Row& row, const YAML::Node& n, const std::string& where) const {
    switch (row.kind) {
      case Kind::kInt:
        return integer(n, where, static_cast<long long>(row.bound.lo),
                       static_cast<long long>(row.bound.hi));
      case Kind::kReal:
        return real(n, where, row);
      case Kind::kBool:
        return boolean(n, where);
      case Kind::kChoice:
        return name(n, where, row.bound.choices);
      case Kind::kSeed:
        return std::to_string(seed(n, where));
      case Kind::kText:
        return scalar(n, where, row.bound_text.empty() ? "a text" : row.bound_text);
      case Kind::kStructure:
        break;
    }
    throw Error("experiment config schema: '" + row.key + "' is not a scalar");
  }

  /// Reads the key of `row` into `target` when the mapping has it.
  void read(const MapView& m, const Row& row, void* target) const {
    if (m.has(row.key)) row.set(target, value(row, m.get(row.key), m.path(row.key)));
  }
  /// Reads every scalar row of the section (and type) that belongs to `owner`.
  void read_rows(const MapView& m, const std::string& section, const std::string& type, Owner owner,
                 void* target) const {
    for (const Row* r : rows_of(section, type)) {
      if (r->owner == owner && r->kind != Kind::kStructure && !r->custom) read(m, *r, target);
    }
  }

  // --- structures

  std::vector<double> number_list(const YAML::Node& n, const std::string& where,
                                  bool non_empty = true) const {
    if (!n.IsSequence()) fail(n, where, "expected a list of numbers");
    std::vector<double> values;
    std::size_t i = 0;
    for (auto it = n.begin(); it != n.end(); ++it, ++i) {
      const std::string w = where + "[" + std::to_string(i) + "]";
      values.push_back(number(*it, w));
    }
    if (non_empty && values.empty()) fail(n, where, "expected a non-empty list of numbers");
    if (values.size() > kMaxCasesPerList) fail(n, where, "too many values");
    return values;
  }

  /// No value twice (labels must be unique).
  void require_distinct(const YAML::Node& n, const std::string& where,
                        const std::vector<double>& values) const {
    std::set<double> seen;
    for (double v : values) {
      if (!seen.insert(v).second) fail(n, where, "value " + shortest(v) + " is listed twice");
    }
  }

  std::vector<std::string> strategies(const YAML::Node& n, const std::string& where) const {
    const std::string expected = "a list of strategies (" + join(preset_names()) + ")";
    if (!n.IsSequence() || n.size() == 0) fail(n, where, "expected " + expected);
    std::vector<std::string> out;
    std::size_t i = 0;
    for (auto it = n.begin(); it != n.end(); ++it, ++i) {
      const std::string w = where + "[" + std::to_string(i) + "]";
      const std::string s = preset_of(*it, w, expected).name;  // aliases by their name
      if (std::find(out.begin(), out.end(), s) != out.end()) {
        fail(*it, w, "strategy '" + s + "' is listed twice");
      }
      out.push_back(s);
    }
    return out;
  }

  Preset preset_of(const YAML::Node& n, const std::string& where,
                   const std::string& expected) const {
    const std::string name = scalar(n, where, expected);
    try {
      return find_preset(name);
    } catch (const InvalidArgument& e) {
      fail(n, where, e.what());
    }
  }

  /// settings: {STRATEGY: {KEY: VALUE}}: each key and value checked against that strategy's table.
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, SettingValue>>>> settings(
      const YAML::Node& n, const std::string& where) const {
    const MapView m(*this, n, where, preset_names());
    std::vector<std::pair<std::string, std::vector<std::pair<std::string, SettingValue>>>> out;
    for (auto it = n.begin(); it != n.end(); ++it) {
      const YAML::Node table = it->second;
      const std::string strategy = it->first.Scalar();
      const std::string w = m.path(strategy);
      if (!table.IsMap()) fail(table, w, "expected a mapping of KEY: VALUE");
      const Pipeline pipeline(find_preset(strategy).spec);
      std::vector<std::pair<std::string, SettingValue>> values;
      for (auto kv = table.begin(); kv != table.end(); ++kv) {
        const YAML::Node k = kv->first;
        const YAML::Node v = kv->second;
        const std::string key = k.IsScalar() ? k.Scalar() : std::string();
        std::string text;
        if (v.IsScalar()) {
          text = v.Scalar();
        } else if (v.IsSequence()) {
          for (std::size_t i = 0; i < v.size(); ++i) {
            text += (i ? "," : "") + scalar(v[i], w + "." + key, "a number");
          }
        } else {
          fail(v, w + "." + key, "expected a value or a list of numbers");
        }
        for (const auto& seen : values) {
          if (seen.first == key) fail(k, w, "duplicate key '" + key + "'");
        }
        try {
          values.emplace_back(key, pipeline.settings().row(key).parse(text));
        } catch (const InvalidArgument& e) {
          fail(k, w, e.what());
        }
      }
      out.emplace_back(strategy, std::move(values));
    }
    return out;
  }

  /// scale: MODE, or {STRATEGY: MODE}.
  void scale(const YAML::Node& n, ExperimentConfig& c) const {
    std::vector<std::string> modes;
    for (const auto& m : kScaleModeNames) modes.push_back(m.name);
    if (n.IsScalar()) {
      c.scale = *find_enum(kScaleModeNames, name(n, "scale", modes));
      return;
    }
    if (!n.IsMap())
      fail(n, "scale", "expected " + join_or(modes) + ", or a mapping STRATEGY: MODE");
    std::set<std::string> seen;
    for (auto it = n.begin(); it != n.end(); ++it) {
      const std::string w = "scale." + (it->first.IsScalar() ? it->first.Scalar() : "?");
      const std::string strategy = preset_of(it->first, "scale", "a strategy").name;
      if (!seen.insert(strategy).second)
        fail(it->first, w, "strategy '" + strategy + "' is given twice");
      c.strategy_scales.emplace_back(strategy,
                                     *find_enum(kScaleModeNames, name(it->second, w, modes)));
    }
  }

  std::string path(const YAML::Node& n, const std::string& where) const {
    std::string s = scalar(n, where, "a file path");
    if (s.empty()) fail(n, where, "expected a file path, got an empty string");
    std::string out;
    std::size_t pos = 0;
    while (true) {
      const std::size_t open = s.find("${", pos);
      if (open == std::string::npos) {
        out += s.substr(pos);
        break;
      }
      const std::size_t close = s.find('}', open);
      if (close == std::string::npos) fail(n, where, "unterminated '${' in '" + s + "'");
      const std::string var = s.substr(open + 2, close - open - 2);
      if (var != "LMALIGN_DATA") {
        fail(n, where,
             "unknown variable '${" + var + "}' in '" + s + "' (only ${LMALIGN_DATA} is expanded)");
      }
      if (options_.data_dir.empty()) {
        fail(n, where,
             "'" + s +
                 "' uses ${LMALIGN_DATA}, but no data folder is known (set the LMALIGN_DATA "
                 "environment variable)");
      }
      out += s.substr(pos, open - pos) + options_.data_dir;
      pos = close + 1;
    }
    fs::path p(out);
    if (p.is_relative()) p = fs::path(base_dir_) / p;
    return p.lexically_normal().string();
  }

  Pose6 pose(const YAML::Node& n, const std::string& where,
             const std::vector<std::string>& varied) const {
    MapView m(*this, n, where, keys_of(kPoseSection));
    for (const std::string& v : varied) {
      if (m.has(v)) {
        fail(m.key_node(v), m.path(v), "this experiment varies " + v + "; remove it from the pose");
      }
    }
    Pose6 p;
    read_rows(m, kPoseSection, "", Owner::kPose, &p);
    return p;
  }

  MapSpec map_spec(const YAML::Node& n, const std::string& where) const {
    MapSpec spec;
    if (n.IsScalar()) {
      spec.path = path(n, where);
      return spec;
    }
    if (!n.IsMap())
      fail(n, where, "expected a map file path, or a mapping with 'map' and optionally 'frames'");
    MapView m(*this, n, where, keys_of(kMapSection));
    m.require("map", "the map file");
    spec.path = path(m.get("map"), m.path("map"));
    if (m.has("frames")) {
      const YAML::Node& f = m.get("frames");
      const std::string w = m.path("frames");
      const std::string expected = "a frame window [first, last] of non-negative frame ids";
      if (!f.IsSequence() || f.size() != 2) fail(f, w, "expected " + expected);
      spec.split = true;
      spec.first_frame_id = integer(f[0], w + "[0]", 0, std::numeric_limits<Id>::max());
      spec.last_frame_id = integer(f[1], w + "[1]", 0, std::numeric_limits<Id>::max());
      if (spec.first_frame_id > spec.last_frame_id) {
        fail(f, w,
             "first frame id " + std::to_string(spec.first_frame_id) + " > last frame id " +
                 std::to_string(spec.last_frame_id));
      }
    }
    for (const char* key : {"retriangulate", "min_parallax_deg"}) {
      if (m.has(key) && !spec.split) {
        fail(m.key_node(key), m.path(key), "only applies to a frame window (add 'frames')");
      }
    }
    read(m, row_of(kMapSection, "", "retriangulate"), &spec);
    if (m.has("min_parallax_deg") && !spec.retriangulate) {
      fail(m.key_node("min_parallax_deg"), m.path("min_parallax_deg"),
           "only applies with retriangulate: true");
    }
    read(m, row_of(kMapSection, "", "min_parallax_deg"), &spec);
    if (m.has("min_observations")) {
      // At least 1 observation in a window, 2 to re-triangulate.
      const Row& row = row_of(kMapSection, "", "min_observations");
      const long long lo = spec.retriangulate ? 2 : (spec.split ? 1 : 0);
      spec.min_observations =
          static_cast<std::size_t>(integer(m.get("min_observations"), m.path("min_observations"),
                                           lo, static_cast<long long>(row.bound.hi)));
    }
    return spec;
  }

  std::vector<Quadrant> quadrants(const YAML::Node& n, const std::string& where) const {
    const std::string expected = "a list of quadrants (+X+Y, -X+Y, -X-Y, +X-Y)";
    if (!n.IsSequence() || n.size() == 0) fail(n, where, "expected " + expected);
    std::vector<Quadrant> out;
    std::size_t i = 0;
    for (auto it = n.begin(); it != n.end(); ++it, ++i) {
      const std::string w = where + "[" + std::to_string(i) + "]";
      const std::string s = scalar(*it, w, expected);
      Quadrant q;
      if (!Quadrant::parse(s, &q))
        fail(*it, w, "unknown quadrant '" + s + "' (expected +X+Y, -X+Y, -X-Y or +X-Y)");
      if (std::find(out.begin(), out.end(), q) != out.end())
        fail(*it, w, "quadrant " + s + " is listed twice");
      out.push_back(q);
    }
    return out;
  }

  /// A list of levels, each within the row's bound: "levels must be in [0, 180] degrees, got 200".
  std::vector<double> levels(const MapView& m, const std::string& key, double lo, double hi) const {
    const Row& row = row_of(kLevels, "", key);
    std::vector<double> values = number_list(m.get(key), m.path(key));
    require_distinct(m.get(key), m.path(key), values);
    for (double v : values) {
      if (v < lo || v > hi) {
        fail(m.get(key), m.path(key),
             "levels must be " +
                 (std::isinf(hi) ? ">= " + shortest(lo)
                                 : "in [" + shortest(lo) + ", " + shortest(hi) + "]") +
                 unit_word(row.unit) + ", got " + shortest(v));
      }
    }
    return values;
  }

  // An experiment's displacement, the keys `varied` left out (they are its own).
  void pose_without(const MapView& m, const std::vector<std::string>& varied,
                    ExperimentSpec* e) const {
    if (m.has("pose")) e->pose = pose(m.get("pose"), m.path("pose"), varied);
  }

  // type neighbourhood: its k values.
  void neighbourhood_keys(const MapView& m, ExperimentSpec* out) const {
    ExperimentSpec& e = *out;
    m.require("k_values", "the neighbourhood sizes to try");
    const YAML::Node& kv = m.get("k_values");
    const std::string w = m.path("k_values");
    if (!kv.IsSequence() || kv.size() == 0)
      fail(kv, w, "expected a non-empty list of integers in [1, 4096]");
    std::size_t i = 0;
    for (auto it = kv.begin(); it != kv.end(); ++it, ++i) {
      const int k = static_cast<int>(integer(*it, w + "[" + std::to_string(i) + "]", 1, kMaxK));
      if (std::find(e.k_values.begin(), e.k_values.end(), k) != e.k_values.end()) {
        fail(*it, w, "k = " + std::to_string(k) + " is listed twice");
      }
      e.k_values.push_back(k);
    }
    pose_without(m, {}, &e);
  }

  // type xy: fixed offsets per quadrant, or an escalation.
  void xy_keys(const MapView& m, const std::string& where, ExperimentSpec* out) const {
    ExperimentSpec& e = *out;
    if (m.has("offsets_m") == m.has("escalate")) {
      fail(m.node(), where,
           "give exactly one of 'offsets_m' (fixed offsets per quadrant) and 'escalate'");
    }
    if (m.has("offsets_m")) {
      if (m.has("quadrants")) {
        fail(m.key_node("quadrants"), m.path("quadrants"),
             "only applies with 'escalate' (offsets_m names its quadrants)");
      }
      const YAML::Node& o = m.get("offsets_m");
      const std::string w = m.path("offsets_m");
      if (!o.IsMap() || o.size() == 0) {
        fail(o, w,
             "expected a mapping from quadrant (+X+Y, -X+Y, -X-Y, +X-Y) to a list of offsets "
             "in metres");
      }
      std::vector<std::string> names;
      for (const Quadrant& q : Quadrant::all()) names.push_back(q.name());
      const MapView om(*this, o, w, names);
      for (auto it = o.begin(); it != o.end(); ++it) {
        Quadrant q;
        Quadrant::parse(it->first.Scalar(), &q);
        const std::string qw = w + "." + q.name();
        std::vector<double> offsets = number_list(it->second, qw);
        require_distinct(it->second, qw, offsets);
        for (double v : offsets) {
          if (!(v > 0.0)) fail(it->second, qw, "offsets must be > 0, got " + shortest(v));
        }
        e.offsets_m.emplace_back(q, std::move(offsets));
      }
    } else {
      e.escalate = true;
      const MapView em(*this, m.get("escalate"), m.path("escalate"), keys_of(kEscalate));
      read_rows(em, kEscalate, "", Owner::kEscalation, &e.escalation);
      if (e.escalation.max_m < e.escalation.start_m) {
        fail(m.get("escalate"), m.path("escalate"),
             "max_m (" + shortest(e.escalation.max_m) + ") < start_m (" +
                 shortest(e.escalation.start_m) + ")");
      }
      if ((e.escalation.max_m - e.escalation.start_m) / e.escalation.step_m > 10000) {
        fail(m.get("escalate"), m.path("escalate"), "more than 10000 levels; use a larger step_m");
      }
      e.quadrants =
          m.has("quadrants") ? quadrants(m.get("quadrants"), m.path("quadrants")) : Quadrant::all();
    }
    pose_without(m, {"x_m", "y_m"}, &e);
  }

  // type basin: its levels and draws.
  void basin_keys(const MapView& m, const std::string& where, const std::string& type,
                  const ExperimentConfig& config, ExperimentSpec* e) const {
    BasinSpec& b = e->basin;
    b.seed = config.seed;
    if (m.has("levels")) {
      const MapView lm(*this, m.get("levels"), m.path("levels"), keys_of(kLevels));
      b.yaw_levels_deg.clear();
      b.translation_levels_m.clear();
      if (lm.has("yaw_deg")) b.yaw_levels_deg = levels(lm, "yaw_deg", 0.0, 180.0);
      if (lm.has("translation_m")) {
        b.translation_levels_m =
            levels(lm, "translation_m", 0.0, std::numeric_limits<double>::infinity());
      }
      if (b.yaw_levels_deg.empty() && b.translation_levels_m.empty()) {
        fail(m.get("levels"), m.path("levels"), "expected yaw_deg and/or translation_m levels");
      }
    }
    read_rows(m, kExperiments, type, Owner::kBasin, &b);
    // levels x samples is unbounded otherwise (up to 2e10 cases): cap it like one list
    // (docs/robustness.md; found by fuzz_experiment_config).
    if (const std::size_t cases = (b.yaw_levels_deg.size() + b.translation_levels_m.size()) *
                                  static_cast<std::size_t>(b.samples);
        cases > kMaxCasesPerList) {
      fail(m.has("samples") ? m.get("samples") : m.node(), where,
           "levels x samples = " + std::to_string(cases) + " cases, more than " +
               std::to_string(kMaxCasesPerList));
    }
  }

  ExperimentSpec experiment(const YAML::Node& n, const std::string& where,
                            const ExperimentConfig& config) const {
    ExperimentSpec e;
    e.line = line_of(n);
    e.k = config.k;
    e.strategies = config.strategies;
    if (!n.IsMap()) fail(n, where, "expected a mapping with 'name' and 'type'");
    // First the type, which decides the allowed keys.
    YAML::Node tnode;
    bool has_type = false;
    for (auto it = n.begin(); it != n.end(); ++it) {
      if (!has_type && it->first.IsScalar() && it->first.Scalar() == "type") {
        tnode = it->second;
        has_type = true;
      }
    }
    const std::string types = enum_names(kExperimentTypeNames);
    if (!has_type) fail(n, where, "missing key 'type' (one of: " + types + ")");
    const std::string type = scalar(tnode, where + ".type", "an experiment type");
    const std::optional<ExperimentType> t = find_enum(kExperimentTypeNames, type);
    if (!t) {
      fail(tnode, where + ".type",
           "unknown experiment type '" + type + "' (expected " +
               join_or(row_of(kExperiments, "", "type").bound.choices) + ")");
    }
    e.type = *t;
    const MapView m(*this, n, where, keys_of(kExperiments, type),
                    " for an experiment of type " + type);

    m.require("name", "a unique name of letters, digits, '_', '-' or '.'");
    read_rows(m, kExperiments, type, Owner::kExperiment, &e);
    if (e.name.empty() || e.name.size() > 64 ||
        !std::all_of(e.name.begin(), e.name.end(), [](unsigned char c) {
          return std::isalnum(c) || c == '_' || c == '-' || c == '.';
        })) {
      fail(m.get("name"), m.path("name"),
           "expected 1-64 letters, digits, '_', '-' or '.', got '" + e.name + "'");
    }
    if (m.has("strategies")) e.strategies = strategies(m.get("strategies"), m.path("strategies"));

    switch (e.type) {
      case ExperimentType::kNeighbourhood: {
        neighbourhood_keys(m, &e);
        break;
      }
      case ExperimentType::kYaw: {
        m.require("yaw_deg", "the yaws to try, degrees");
        e.yaw_deg = number_list(m.get("yaw_deg"), m.path("yaw_deg"));
        require_distinct(m.get("yaw_deg"), m.path("yaw_deg"), e.yaw_deg);
        pose_without(m, {"yaw_deg"}, &e);
        break;
      }
      case ExperimentType::kXy: {
        xy_keys(m, where, &e);
        break;
      }
      case ExperimentType::kXyYaw: {
        m.require("yaw_deg", "the yaws to combine with each quadrant, degrees");
        e.yaw_deg = number_list(m.get("yaw_deg"), m.path("yaw_deg"));
        require_distinct(m.get("yaw_deg"), m.path("yaw_deg"), e.yaw_deg);
        e.quadrants = m.has("quadrants") ? quadrants(m.get("quadrants"), m.path("quadrants"))
                                         : Quadrant::all();
        pose_without(m, {"x_m", "y_m", "yaw_deg"}, &e);
        break;
      }
      case ExperimentType::kPoses: {
        m.require("poses", "a list of displacements {x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg}");
        const YAML::Node& p = m.get("poses");
        if (!p.IsSequence() || p.size() == 0) {
          fail(p, m.path("poses"),
               "expected a non-empty list of displacements {x_m, y_m, z_m, roll_deg, pitch_deg, "
               "yaw_deg}");
        }
        std::size_t i = 0;
        for (auto it = p.begin(); it != p.end(); ++it, ++i) {
          e.poses.push_back(pose(*it, m.path("poses") + "[" + std::to_string(i) + "]", {}));
        }
        break;
      }
      case ExperimentType::kBasin: {
        basin_keys(m, where, type, config, &e);
        break;
      }
      case ExperimentType::kRandom: {
        e.random.seed = config.seed;
        read_rows(m, kExperiments, type, Owner::kRandom, &e.random);
        break;
      }
    }
    return e;
  }

  ExperimentConfig config(const YAML::Node& root) const {
    ExperimentConfig c;
    c.path = file_;
    c.name = fs::path(file_).stem().string();
    if (!root.IsDefined() || root.IsNull()) {
      fail_line(0, "", "empty config (expected a mapping with source, target and experiments)");
    }
    const MapView m(*this, root, "", keys_of(kTop));
    if (m.has("description")) scalar(m.get("description"), "description", "a text");
    m.require("source", "the source map: a path, or {map: PATH, frames: [FIRST, LAST]}");
    m.require("target", "the target map: a path, or {map: PATH, frames: [FIRST, LAST]}");
    m.require("experiments", "a list of experiments");
    c.source = map_spec(m.get("source"), "source");
    c.target = map_spec(m.get("target"), "target");
    if (m.has("ground_truth")) {
      const YAML::Node& g = m.get("ground_truth");
      if (g.IsNull()) {
        c.ground_truth.kind = GroundTruthSpec::Kind::kNone;
      } else {
        const std::string s = scalar(g, "ground_truth", "identity, none, or a 4x4 transform file");
        if (s == "identity") {
          c.ground_truth.kind = GroundTruthSpec::Kind::kIdentity;
        } else if (s == "none") {
          c.ground_truth.kind = GroundTruthSpec::Kind::kNone;
        } else {
          c.ground_truth.kind = GroundTruthSpec::Kind::kFile;
          c.ground_truth.path = path(g, "ground_truth");
        }
      }
    }
    if (m.has("strategies")) c.strategies = strategies(m.get("strategies"), "strategies");
    if (m.has("settings")) c.settings = settings(m.get("settings"), "settings");
    if (m.has("scale")) scale(m.get("scale"), c);
    read_rows(m, kTop, "", Owner::kConfig, &c);
    if (m.has("success")) {
      const MapView s(*this, m.get("success"), "success", keys_of(kSuccessSection));
      read_rows(s, kSuccessSection, "", Owner::kSuccess, &c.success);
    }

    const YAML::Node& ex = m.get("experiments");
    if (!ex.IsSequence() || ex.size() == 0)
      fail(ex, "experiments", "expected a non-empty list of experiments");
    std::map<std::string, std::size_t> names;
    std::size_t i = 0;
    for (auto it = ex.begin(); it != ex.end(); ++it, ++i) {
      const std::string w = "experiments[" + std::to_string(i) + "]";
      ExperimentSpec e = experiment(*it, w, c);
      if (names.count(e.name) != 0) {
        fail(*it, w + ".name",
             "experiment name '" + e.name + "' is used twice (first at line " +
                 std::to_string(names.at(e.name)) + ")");
      }
      names.emplace(e.name, e.line);
      c.experiments.push_back(std::move(e));
    }
    return c;
  }

 private:
  std::string file_;
  std::string base_dir_;
  ConfigLoadOptions options_;
};

// ----------------------------------------------------------------------------- the writer

void emit_number(YAML::Emitter& e, double v) {
  if (std::isinf(v)) {
    e << (v > 0 ? ".inf" : "-.inf");
  } else {
    e << shortest(v);
  }
}

void emit_numbers(YAML::Emitter& e, const std::vector<double>& values) {
  e << YAML::Flow << YAML::BeginSeq;
  for (double v : values) emit_number(e, v);
  e << YAML::EndSeq;
}

void emit_strategies(YAML::Emitter& e, const std::vector<std::string>& s) {
  e << YAML::Flow << YAML::BeginSeq;
  for (const std::string& x : s) e << x;
  e << YAML::EndSeq;
}

void emit_quadrants(YAML::Emitter& e, const std::vector<Quadrant>& q) {
  e << YAML::Flow << YAML::BeginSeq;
  for (const Quadrant& x : q) e << x.name();
  e << YAML::EndSeq;
}

/// One scalar row's value of `source` (nothing for an optional not given).
void emit_row(YAML::Emitter& e, const Row& row, const void* source) {
  const std::optional<SettingValue> v = row.get(source);
  if (!v) return;
  e << YAML::Key << row.key << YAML::Value;
  if (const double* d = std::get_if<double>(&*v)) {
    emit_number(e, *d);
  } else if (row.kind == Kind::kText) {
    e << YAML::DoubleQuoted << std::get<std::string>(*v);
  } else {
    e << value_text(*v);
  }
}

/// The rows of a section in table order: scalar rows of `owner` from `source`, the others by
/// `structure(key)` (which writes them, or nothing).
void emit_section(YAML::Emitter& e, const std::string& section, const std::string& type,
                  const std::map<Owner, const void*>& sources,
                  const std::function<void(const std::string&)>& structure) {
  for (const Row* r : rows_of(section, type)) {
    const auto source = sources.find(r->owner);
    if (r->kind == Kind::kStructure || r->custom || source == sources.end()) {
      structure(r->key);
    } else {
      emit_row(e, *r, source->second);
    }
  }
}

void emit_pose(YAML::Emitter& e, const Pose6& p, const std::vector<std::string>& skip) {
  e << YAML::Flow << YAML::BeginMap;
  for (const Row* r : rows_of(kPoseSection)) {
    if (std::find(skip.begin(), skip.end(), r->key) == skip.end()) emit_row(e, *r, &p);
  }
  e << YAML::EndMap;
}

void emit_map_spec(YAML::Emitter& e, const MapSpec& s) {
  e << YAML::BeginMap;
  emit_section(e, kMapSection, "", {}, [&](const std::string& key) {
    if (key == "map") {
      e << YAML::Key << "map" << YAML::Value << YAML::DoubleQuoted << s.path;
    } else if (key == "min_observations") {
      e << YAML::Key << key << YAML::Value << s.min_observations;
    } else if (key == "frames" && s.split) {
      e << YAML::Key << "frames" << YAML::Value << YAML::Flow << YAML::BeginSeq << s.first_frame_id
        << s.last_frame_id << YAML::EndSeq;
    } else if ((key == "retriangulate" && s.split) ||
               (key == "min_parallax_deg" && s.retriangulate)) {
      emit_row(e, row_of(kMapSection, "", key), &s);
    }
  });
  e << YAML::EndMap;
}

void emit_experiment(YAML::Emitter& e, const ExperimentSpec& x) {
  const std::string type = to_string(x.type);
  e << YAML::BeginMap;
  const std::map<Owner, const void*> sources{
      {Owner::kExperiment, &x}, {Owner::kBasin, &x.basin}, {Owner::kRandom, &x.random}};
  emit_section(e, kExperiments, type, sources, [&](const std::string& key) {
    if (key == "type") {
      e << YAML::Key << "type" << YAML::Value << type;
    } else if (key == "strategies") {
      e << YAML::Key << key << YAML::Value;
      emit_strategies(e, x.strategies);
    } else if (key == "k_values") {
      e << YAML::Key << key << YAML::Value << YAML::Flow << x.k_values;
    } else if (key == "yaw_deg") {
      e << YAML::Key << key << YAML::Value;
      emit_numbers(e, x.yaw_deg);
    } else if (key == "offsets_m" && !x.escalate) {
      e << YAML::Key << key << YAML::Value << YAML::BeginMap;
      for (const auto& [q, offsets] : x.offsets_m) {
        e << YAML::Key << q.name() << YAML::Value;
        emit_numbers(e, offsets);
      }
      e << YAML::EndMap;
    } else if (key == "escalate" && x.escalate) {
      e << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginMap;
      emit_section(e, kEscalate, "", {{Owner::kEscalation, &x.escalation}},
                   [](const std::string&) {});
      e << YAML::EndMap;
    } else if (key == "quadrants" && (x.escalate || x.type == ExperimentType::kXyYaw)) {
      e << YAML::Key << key << YAML::Value;
      emit_quadrants(e, x.quadrants);
    } else if (key == "pose") {
      e << YAML::Key << key << YAML::Value;
      switch (x.type) {
        case ExperimentType::kYaw:
          emit_pose(e, x.pose, {"yaw_deg"});
          break;
        case ExperimentType::kXy:
          emit_pose(e, x.pose, {"x_m", "y_m"});
          break;
        case ExperimentType::kXyYaw:
          emit_pose(e, x.pose, {"x_m", "y_m", "yaw_deg"});
          break;
        default:
          emit_pose(e, x.pose, {});
      }
    } else if (key == "poses") {
      e << YAML::Key << key << YAML::Value << YAML::BeginSeq;
      for (const Pose6& p : x.poses) emit_pose(e, p, {});
      e << YAML::EndSeq;
    } else if (key == "levels") {
      e << YAML::Key << key << YAML::Value << YAML::BeginMap;
      if (!x.basin.yaw_levels_deg.empty()) {
        e << YAML::Key << "yaw_deg" << YAML::Value;
        emit_numbers(e, x.basin.yaw_levels_deg);
      }
      if (!x.basin.translation_levels_m.empty()) {
        e << YAML::Key << "translation_m" << YAML::Value;
        emit_numbers(e, x.basin.translation_levels_m);
      }
      e << YAML::EndMap;
    }
  });
  e << YAML::EndMap;
}

}  // namespace

ExperimentConfig parse_experiment_config(const std::string& yaml_text, const std::string& name,
                                         const std::string& base_dir,
                                         const ConfigLoadOptions& options) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw ParseError(name, e.mark.is_null() ? 0 : static_cast<std::size_t>(e.mark.line) + 1,
                     "YAML syntax error: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw ParseError(name, 0, std::string("YAML error: ") + e.what());
  }
  std::error_code ec;
  fs::path base = fs::absolute(base_dir.empty() ? fs::path(".") : fs::path(base_dir), ec);
  if (ec) base = base_dir;
  const Parser parser(name, base.lexically_normal().string(), options);
  try {
    return parser.config(root);
  } catch (const YAML::Exception& e) {
    // Should not happen (every access is checked); never let yaml-cpp's types escape.
    throw ParseError(name, e.mark.is_null() ? 0 : static_cast<std::size_t>(e.mark.line) + 1,
                     std::string("YAML error: ") + e.what());
  }
}

ExperimentConfig load_experiment_config(const std::string& path, const ConfigLoadOptions& options) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    throw IoError("cannot read config '" + path + "': " + std::strerror(EISDIR));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open config '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw IoError("cannot read config '" + path + "': read error");
  const fs::path parent = fs::path(path).parent_path();
  return parse_experiment_config(text.str(), path, parent.empty() ? "." : parent.string(), options);
}

std::string resolved_config_yaml(const ExperimentConfig& c) {
  YAML::Emitter e;
  e << YAML::Comment("Resolved by lmalign experiment from " + c.path +
                     ": every default filled in, every path absolute.");
  e << YAML::Newline;
  e << YAML::BeginMap;
  emit_section(e, kTop, "", {{Owner::kConfig, &c}}, [&](const std::string& key) {
    if (key == "source" || key == "target") {
      e << YAML::Key << key << YAML::Value;
      emit_map_spec(e, key == "source" ? c.source : c.target);
    } else if (key == "ground_truth") {
      e << YAML::Key << key << YAML::Value;
      switch (c.ground_truth.kind) {
        case GroundTruthSpec::Kind::kNone:
          e << "none";
          break;
        case GroundTruthSpec::Kind::kIdentity:
          e << "identity";
          break;
        case GroundTruthSpec::Kind::kFile:
          e << YAML::DoubleQuoted << c.ground_truth.path;
          break;
      }
    } else if (key == "strategies") {
      e << YAML::Key << key << YAML::Value;
      emit_strategies(e, c.strategies);
    } else if (key == "scale") {
      e << YAML::Key << key << YAML::Value;
      if (c.strategy_scales.empty()) {
        e << to_string(c.scale);
      } else {
        e << YAML::Flow << YAML::BeginMap;
        for (const auto& [s, mode] : c.strategy_scales) {
          e << YAML::Key << s << YAML::Value << to_string(mode);
        }
        e << YAML::EndMap;
      }
    } else if (key == "settings" && !c.settings.empty()) {
      e << YAML::Key << key << YAML::Value << YAML::BeginMap;
      for (const auto& [strategy, values] : c.settings) {
        const Pipeline pipeline(find_preset(strategy).spec);
        e << YAML::Key << strategy << YAML::Value << YAML::BeginMap;
        for (const auto& [k, value] : values) {
          e << YAML::Key << k << YAML::Value;
          if (std::holds_alternative<std::vector<double>>(value)) {
            emit_numbers(e, std::get<std::vector<double>>(value));
          } else if (std::holds_alternative<double>(value)) {
            emit_number(e, std::get<double>(value));
          } else {
            e << pipeline.settings().row(k).text(value);
          }
        }
        e << YAML::EndMap;
      }
      e << YAML::EndMap;
    } else if (key == "success") {
      e << YAML::Key << key << YAML::Value << YAML::BeginMap;
      emit_section(e, kSuccessSection, "", {{Owner::kSuccess, &c.success}},
                   [](const std::string&) {});
      e << YAML::EndMap;
    } else if (key == "experiments") {
      e << YAML::Key << key << YAML::Value << YAML::BeginSeq;
      for (const ExperimentSpec& x : c.experiments) emit_experiment(e, x);
      e << YAML::EndSeq;
    }
  });
  e << YAML::EndMap;
  if (!e.good()) throw Error("resolved_config_yaml: YAML emitter error: " + e.GetLastError());
  return std::string(e.c_str()) + "\n";
}

void select_experiments(ExperimentConfig& config, const std::vector<std::string>& names) {
  std::vector<std::string> known;
  for (const ExperimentSpec& e : config.experiments) known.push_back(e.name);
  for (const std::string& n : names) {
    if (std::find(known.begin(), known.end(), n) == known.end()) {
      throw InvalidArgument("no experiment named '" + n + "' in " + config.path +
                            " (it has: " + join(known) + ")");
    }
  }
  std::vector<ExperimentSpec> kept;
  for (ExperimentSpec& e : config.experiments) {
    if (std::find(names.begin(), names.end(), e.name) != names.end()) kept.push_back(std::move(e));
  }
  config.experiments = std::move(kept);
}

}  // namespace lmalign
