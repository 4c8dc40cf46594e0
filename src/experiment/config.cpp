// Strict YAML reading of experiment configs (docs/experiments.md, "Config"). Every error names
// the file, the 1-based line (yaml-cpp's mark) and the key path: "paper.yaml:12:
// experiments[1].yaw_deg: expected a list of numbers".
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

std::string to_string(ExperimentType type) {
  switch (type) {
    case ExperimentType::kNeighbourhood:
      return "k";
    case ExperimentType::kYaw:
      return "yaw";
    case ExperimentType::kXy:
      return "xy";
    case ExperimentType::kXyYaw:
      return "xy_yaw";
    case ExperimentType::kPoses:
      return "poses";
    case ExperimentType::kBasin:
      return "basin";
    case ExperimentType::kRandom:
      return "random";
  }
  return "?";
}

std::string to_string(YawPivot pivot) {
  switch (pivot) {
    case YawPivot::kLandmark:
      return "landmark";
    case YawPivot::kCentroid:
      return "centroid";
    case YawPivot::kOrigin:
      return "origin";
  }
  return "?";
}

std::string to_string(TranslationDirections d) {
  return d == TranslationDirections::kXy ? "xy" : "xyz";
}

namespace {

namespace fs = std::filesystem;
using detail::shortest;

constexpr int kMaxK = 4096;
constexpr std::size_t kMaxCasesPerList = 100000;

std::string join(const std::vector<std::string>& items, const std::string& sep = ", ") {
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) s += (i ? sep : "") + items[i];
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

  /// A mapping with known keys: rejects anything else, unknown keys and duplicates.
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
          p.fail(key, where_,
                 "unknown key '" + k + "'" + context + " (expected one of: " + join(allowed) + ")");
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
    const std::string& where() const { return where_; }
    std::size_t line() const { return line_of(node_); }
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

  YawPivot pivot(const YAML::Node& n, const std::string& where) const {
    const std::string s = scalar(n, where, "landmark, centroid or origin");
    if (s == "landmark") return YawPivot::kLandmark;
    if (s == "centroid") return YawPivot::kCentroid;
    if (s != "origin") fail(n, where, "expected landmark, centroid or origin, got '" + s + "'");
    return YawPivot::kOrigin;
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

  double positive(const YAML::Node& n, const std::string& where, bool allow_inf = false) const {
    const double v = number(n, where, allow_inf);
    if (!(v > 0.0)) fail(n, where, "must be > 0, got " + shortest(v));
    return v;
  }

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
      const std::string name = scalar(*it, w, expected);
      if (!is_preset_name(name)) {
        std::string nearest;
        try {
          (void)find_preset(name);
        } catch (const InvalidArgument& e) {
          fail(*it, w, e.what());
        }
      }
      const std::string s = find_preset(name).name;  // aliases by their name
      if (std::find(out.begin(), out.end(), s) != out.end()) {
        fail(*it, w, "strategy '" + s + "' is listed twice");
      }
      out.push_back(s);
    }
    return out;
  }

  /// settings: {STRATEGY: {KEY: VALUE}}: each key and value checked against that strategy's table.
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, SettingValue>>>> settings(
      const YAML::Node& n, const std::string& where) const {
    std::vector<std::string> names = preset_names();
    const MapView m(*this, n, where, names);
    std::vector<std::pair<std::string, std::vector<std::pair<std::string, SettingValue>>>> out;
    for (auto it = n.begin(); it != n.end(); ++it) {
      const YAML::Node name = it->first;
      const YAML::Node table = it->second;
      const std::string strategy = name.Scalar();
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
    static const std::vector<std::string> keys{"x_m",      "y_m",       "z_m",
                                               "roll_deg", "pitch_deg", "yaw_deg"};
    MapView m(*this, n, where, keys);
    for (const std::string& v : varied) {
      if (m.has(v)) {
        fail(m.key_node(v), m.path(v), "this experiment varies " + v + "; remove it from the pose");
      }
    }
    Pose6 p;
    double* fields[] = {&p.x_m, &p.y_m, &p.z_m, &p.roll_deg, &p.pitch_deg, &p.yaw_deg};
    for (std::size_t i = 0; i < keys.size(); ++i) {
      if (m.has(keys[i])) *fields[i] = number(m.get(keys[i]), m.path(keys[i]));
    }
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
    MapView m(*this, n, where,
              {"map", "min_observations", "frames", "retriangulate", "min_parallax_deg"});
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
    if (m.has("retriangulate"))
      spec.retriangulate = boolean(m.get("retriangulate"), m.path("retriangulate"));
    if (m.has("min_parallax_deg")) {
      if (!spec.retriangulate) {
        fail(m.key_node("min_parallax_deg"), m.path("min_parallax_deg"),
             "only applies with retriangulate: true");
      }
      spec.min_parallax_deg = number(m.get("min_parallax_deg"), m.path("min_parallax_deg"));
      if (spec.min_parallax_deg < 0.0 || spec.min_parallax_deg > 180.0) {
        fail(m.get("min_parallax_deg"), m.path("min_parallax_deg"),
             "must be in [0, 180] degrees, got " + shortest(spec.min_parallax_deg));
      }
    }
    if (m.has("min_observations")) {
      const long long lo = spec.retriangulate ? 2 : (spec.split ? 1 : 0);
      spec.min_observations = static_cast<std::size_t>(
          integer(m.get("min_observations"), m.path("min_observations"), lo, 1000000));
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
    if (!has_type)
      fail(n, where, "missing key 'type' (one of: k, yaw, xy, xy_yaw, poses, basin, random)");
    const std::string type = scalar(tnode, where + ".type", "an experiment type");
    std::vector<std::string> keys{"name", "type", "strategies"};
    if (type == "k") {
      e.type = ExperimentType::kNeighbourhood;
      keys.insert(keys.end(), {"k_values", "pose"});
    } else if (type == "yaw") {
      e.type = ExperimentType::kYaw;
      keys.insert(keys.end(), {"k", "yaw_deg", "pose"});
    } else if (type == "xy") {
      e.type = ExperimentType::kXy;
      keys.insert(keys.end(), {"k", "offsets_m", "escalate", "quadrants", "pose"});
    } else if (type == "xy_yaw") {
      e.type = ExperimentType::kXyYaw;
      keys.insert(keys.end(), {"k", "offset_m", "yaw_deg", "quadrants", "pose"});
    } else if (type == "poses") {
      e.type = ExperimentType::kPoses;
      keys.insert(keys.end(), {"k", "poses"});
    } else if (type == "basin") {
      e.type = ExperimentType::kBasin;
      keys.insert(keys.end(),
                  {"k", "levels", "samples", "seed", "yaw_pivot", "translation_directions"});
    } else if (type == "random") {
      e.type = ExperimentType::kRandom;
      keys.insert(keys.end(), {"k", "samples", "seed", "yaw_deg", "translation_m", "roll_pitch_deg",
                               "pivot", "up_axis"});
    } else {
      fail(tnode, where + ".type",
           "unknown experiment type '" + type +
               "' (expected k, yaw, xy, xy_yaw, poses, basin or random)");
    }
    const MapView m(*this, n, where, keys, " for an experiment of type " + type);

    m.require("name", "a unique name of letters, digits, '_', '-' or '.'");
    e.name = scalar(m.get("name"), m.path("name"), "a name");
    if (e.name.empty() || e.name.size() > 64 ||
        !std::all_of(e.name.begin(), e.name.end(), [](unsigned char c) {
          return std::isalnum(c) || c == '_' || c == '-' || c == '.';
        })) {
      fail(m.get("name"), m.path("name"),
           "expected 1-64 letters, digits, '_', '-' or '.', got '" + e.name + "'");
    }
    if (m.has("strategies")) e.strategies = strategies(m.get("strategies"), m.path("strategies"));
    if (m.has("k")) e.k = static_cast<int>(integer(m.get("k"), m.path("k"), 1, kMaxK));

    switch (e.type) {
      case ExperimentType::kNeighbourhood: {
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
        if (m.has("pose")) e.pose = pose(m.get("pose"), m.path("pose"), {});
        break;
      }
      case ExperimentType::kYaw: {
        m.require("yaw_deg", "the yaws to try, degrees");
        e.yaw_deg = number_list(m.get("yaw_deg"), m.path("yaw_deg"));
        require_distinct(m.get("yaw_deg"), m.path("yaw_deg"), e.yaw_deg);
        if (m.has("pose")) e.pose = pose(m.get("pose"), m.path("pose"), {"yaw_deg"});
        break;
      }
      case ExperimentType::kXy: {
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
          const MapView em(*this, m.get("escalate"), m.path("escalate"),
                           {"start_m", "step_m", "max_m", "stop"});
          if (em.has("stop")) {
            const std::string st = scalar(em.get("stop"), em.path("stop"), "any or all");
            if (st != "any" && st != "all")
              fail(em.get("stop"), em.path("stop"), "expected any or all, got '" + st + "'");
            e.escalation.stop_when_all_fail = st == "all";
          }
          if (em.has("start_m"))
            e.escalation.start_m = positive(em.get("start_m"), em.path("start_m"));
          if (em.has("step_m")) e.escalation.step_m = positive(em.get("step_m"), em.path("step_m"));
          if (em.has("max_m")) e.escalation.max_m = positive(em.get("max_m"), em.path("max_m"));
          if (e.escalation.max_m < e.escalation.start_m) {
            fail(m.get("escalate"), m.path("escalate"),
                 "max_m (" + shortest(e.escalation.max_m) + ") < start_m (" +
                     shortest(e.escalation.start_m) + ")");
          }
          if ((e.escalation.max_m - e.escalation.start_m) / e.escalation.step_m > 10000) {
            fail(m.get("escalate"), m.path("escalate"),
                 "more than 10000 levels; use a larger step_m");
          }
          e.quadrants = m.has("quadrants") ? quadrants(m.get("quadrants"), m.path("quadrants"))
                                           : Quadrant::all();
        }
        if (m.has("pose")) e.pose = pose(m.get("pose"), m.path("pose"), {"x_m", "y_m"});
        break;
      }
      case ExperimentType::kXyYaw: {
        m.require("yaw_deg", "the yaws to combine with each quadrant, degrees");
        e.yaw_deg = number_list(m.get("yaw_deg"), m.path("yaw_deg"));
        require_distinct(m.get("yaw_deg"), m.path("yaw_deg"), e.yaw_deg);
        if (m.has("offset_m")) e.offset_m = positive(m.get("offset_m"), m.path("offset_m"));
        e.quadrants = m.has("quadrants") ? quadrants(m.get("quadrants"), m.path("quadrants"))
                                         : Quadrant::all();
        if (m.has("pose")) e.pose = pose(m.get("pose"), m.path("pose"), {"x_m", "y_m", "yaw_deg"});
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
        BasinSpec& b = e.basin;
        b.seed = config.seed;
        if (m.has("levels")) {
          const MapView lm(*this, m.get("levels"), m.path("levels"), {"yaw_deg", "translation_m"});
          b.yaw_levels_deg.clear();
          b.translation_levels_m.clear();
          if (lm.has("yaw_deg")) {
            b.yaw_levels_deg = number_list(lm.get("yaw_deg"), lm.path("yaw_deg"));
            require_distinct(lm.get("yaw_deg"), lm.path("yaw_deg"), b.yaw_levels_deg);
            for (double v : b.yaw_levels_deg) {
              if (v < 0.0 || v > 180.0) {
                fail(lm.get("yaw_deg"), lm.path("yaw_deg"),
                     "levels must be in [0, 180] degrees, got " + shortest(v));
              }
            }
          }
          if (lm.has("translation_m")) {
            b.translation_levels_m = number_list(lm.get("translation_m"), lm.path("translation_m"));
            require_distinct(lm.get("translation_m"), lm.path("translation_m"),
                             b.translation_levels_m);
            for (double v : b.translation_levels_m) {
              if (v < 0.0)
                fail(lm.get("translation_m"), lm.path("translation_m"),
                     "levels must be >= 0 metres, got " + shortest(v));
            }
          }
          if (b.yaw_levels_deg.empty() && b.translation_levels_m.empty()) {
            fail(m.get("levels"), m.path("levels"), "expected yaw_deg and/or translation_m levels");
          }
        }
        if (m.has("samples"))
          b.samples = static_cast<int>(integer(m.get("samples"), m.path("samples"), 1, 100000));
        // levels x samples is unbounded otherwise (up to 2e10 cases): cap it like one list
        // (docs/robustness.md; found by fuzz_experiment_config).
        if (const std::size_t cases = (b.yaw_levels_deg.size() + b.translation_levels_m.size()) *
                                      static_cast<std::size_t>(b.samples);
            cases > kMaxCasesPerList) {
          fail(m.has("samples") ? m.get("samples") : m.node(), where,
               "levels x samples = " + std::to_string(cases) + " cases, more than " +
                   std::to_string(kMaxCasesPerList));
        }
        if (m.has("seed")) b.seed = seed(m.get("seed"), m.path("seed"));
        if (m.has("yaw_pivot")) b.yaw_pivot = pivot(m.get("yaw_pivot"), m.path("yaw_pivot"));
        if (m.has("translation_directions")) {
          const std::string s = scalar(m.get("translation_directions"),
                                       m.path("translation_directions"), "xy or xyz");
          if (s == "xy") {
            b.translation_directions = TranslationDirections::kXy;
          } else if (s == "xyz") {
            b.translation_directions = TranslationDirections::kXyz;
          } else {
            fail(m.get("translation_directions"), m.path("translation_directions"),
                 "expected xy or xyz, got '" + s + "'");
          }
        }
        break;
      }
      case ExperimentType::kRandom: {
        RandomStartSpec& r = e.random;
        r.seed = config.seed;
        if (m.has("samples"))
          r.samples = static_cast<int>(integer(m.get("samples"), m.path("samples"), 1,
                                               static_cast<long long>(kMaxCasesPerList)));
        if (m.has("seed")) r.seed = seed(m.get("seed"), m.path("seed"));
        auto bounded = [&](const char* key, double lo, double hi, const std::string& unit) {
          const double v = number(m.get(key), m.path(key));
          if (!(v >= lo && v <= hi))
            fail(m.get(key), m.path(key),
                 "expected a number in [" + shortest(lo) + ", " +
                     (std::isinf(hi) ? std::string("inf") : shortest(hi)) + "] " + unit + ", got " +
                     shortest(v));
          return v;
        };
        if (m.has("yaw_deg")) r.yaw_deg = bounded("yaw_deg", 0.0, 180.0, "degrees");
        if (m.has("translation_m")) r.translation_m = bounded("translation_m", 0.0, 1e6, "metres");
        if (m.has("roll_pitch_deg"))
          r.roll_pitch_deg = bounded("roll_pitch_deg", 0.0, 90.0, "degrees");
        if (m.has("pivot")) r.pivot = pivot(m.get("pivot"), m.path("pivot"));
        if (m.has("up_axis")) {
          const std::string s = scalar(m.get("up_axis"), m.path("up_axis"), "x, y or z");
          if (s != "x" && s != "y" && s != "z")
            fail(m.get("up_axis"), m.path("up_axis"), "expected x, y or z, got '" + s + "'");
          r.up_axis = parse_up_axis(s);
        }
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
    const MapView m(*this, root, "",
                    {"description", "source", "target", "ground_truth", "strategies", "k",
                     "max_iterations", "max_distance_m", "settings", "covariance_norm", "success",
                     "seed", "plot_case", "experiments"});
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
    if (m.has("k")) c.k = static_cast<int>(integer(m.get("k"), "k", 1, kMaxK));
    if (m.has("max_iterations")) {
      c.max_iterations =
          static_cast<int>(integer(m.get("max_iterations"), "max_iterations", 1, 1000000));
    }
    if (m.has("max_distance_m"))
      c.max_distance_m = positive(m.get("max_distance_m"), "max_distance_m", true);
    if (m.has("covariance_norm")) {
      const std::string s =
          scalar(m.get("covariance_norm"), "covariance_norm", "spectral or frobenius");
      if (s == "spectral") {
        c.covariance_norm = CovarianceNorm::kSpectral;
      } else if (s == "frobenius") {
        c.covariance_norm = CovarianceNorm::kFrobenius;
      } else {
        fail(m.get("covariance_norm"), "covariance_norm",
             "expected spectral or frobenius, got '" + s + "'");
      }
    }
    if (m.has("success")) {
      const MapView s(*this, m.get("success"), "success",
                      {"rotation_deg", "translation_m", "score_m2"});
      if (s.has("rotation_deg"))
        c.success.rotation_deg = positive(s.get("rotation_deg"), s.path("rotation_deg"));
      if (s.has("translation_m"))
        c.success.translation_m = positive(s.get("translation_m"), s.path("translation_m"));
      if (s.has("score_m2")) c.success.score_m2 = positive(s.get("score_m2"), s.path("score_m2"));
    }
    if (m.has("seed")) c.seed = seed(m.get("seed"), "seed");
    if (m.has("plot_case"))
      c.plot_case = scalar(m.get("plot_case"), "plot_case", "a case index or <experiment>/<label>");

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

void emit_pose(YAML::Emitter& e, const Pose6& p, const std::vector<std::string>& skip) {
  e << YAML::Flow << YAML::BeginMap;
  const std::pair<const char*, double> fields[] = {{"x_m", p.x_m},
                                                   {"y_m", p.y_m},
                                                   {"z_m", p.z_m},
                                                   {"roll_deg", p.roll_deg},
                                                   {"pitch_deg", p.pitch_deg},
                                                   {"yaw_deg", p.yaw_deg}};
  for (const auto& [key, value] : fields) {
    if (std::find(skip.begin(), skip.end(), key) != skip.end()) continue;
    e << YAML::Key << key << YAML::Value;
    emit_number(e, value);
  }
  e << YAML::EndMap;
}

void emit_map_spec(YAML::Emitter& e, const MapSpec& s) {
  e << YAML::BeginMap;
  e << YAML::Key << "map" << YAML::Value << YAML::DoubleQuoted << s.path;
  e << YAML::Key << "min_observations" << YAML::Value << s.min_observations;
  if (s.split) {
    e << YAML::Key << "frames" << YAML::Value << YAML::Flow << YAML::BeginSeq << s.first_frame_id
      << s.last_frame_id << YAML::EndSeq;
    e << YAML::Key << "retriangulate" << YAML::Value << (s.retriangulate ? "true" : "false");
    if (s.retriangulate) {
      e << YAML::Key << "min_parallax_deg" << YAML::Value;
      emit_number(e, s.min_parallax_deg);
    }
  }
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
  e << YAML::Key << "source" << YAML::Value;
  emit_map_spec(e, c.source);
  e << YAML::Key << "target" << YAML::Value;
  emit_map_spec(e, c.target);
  e << YAML::Key << "ground_truth" << YAML::Value;
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
  e << YAML::Key << "strategies" << YAML::Value;
  emit_strategies(e, c.strategies);
  e << YAML::Key << "k" << YAML::Value << c.k;
  if (c.max_iterations) e << YAML::Key << "max_iterations" << YAML::Value << *c.max_iterations;
  if (c.max_distance_m) {
    e << YAML::Key << "max_distance_m" << YAML::Value;
    emit_number(e, *c.max_distance_m);
  }
  if (!c.settings.empty()) {
    e << YAML::Key << "settings" << YAML::Value << YAML::BeginMap;
    for (const auto& [strategy, values] : c.settings) {
      const Pipeline pipeline(find_preset(strategy).spec);
      e << YAML::Key << strategy << YAML::Value << YAML::BeginMap;
      for (const auto& [key, value] : values) {
        const std::string text = pipeline.settings().row(key).text(value);
        e << YAML::Key << key << YAML::Value;
        if (std::holds_alternative<std::vector<double>>(value)) {
          emit_numbers(e, std::get<std::vector<double>>(value));
        } else if (std::holds_alternative<double>(value)) {
          emit_number(e, std::get<double>(value));
        } else {
          e << text;
        }
      }
      e << YAML::EndMap;
    }
    e << YAML::EndMap;
  }
  e << YAML::Key << "covariance_norm" << YAML::Value << to_string(c.covariance_norm);
  e << YAML::Key << "success" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "rotation_deg" << YAML::Value;
  emit_number(e, c.success.rotation_deg);
  e << YAML::Key << "translation_m" << YAML::Value;
  emit_number(e, c.success.translation_m);
  e << YAML::Key << "score_m2" << YAML::Value;
  emit_number(e, c.success.score_m2);
  e << YAML::EndMap;
  e << YAML::Key << "seed" << YAML::Value << std::to_string(c.seed);
  if (!c.plot_case.empty())
    e << YAML::Key << "plot_case" << YAML::Value << YAML::DoubleQuoted << c.plot_case;
  e << YAML::Key << "experiments" << YAML::Value << YAML::BeginSeq;
  for (const ExperimentSpec& x : c.experiments) {
    e << YAML::BeginMap;
    e << YAML::Key << "name" << YAML::Value << x.name;
    e << YAML::Key << "type" << YAML::Value << to_string(x.type);
    e << YAML::Key << "strategies" << YAML::Value;
    emit_strategies(e, x.strategies);
    if (x.type != ExperimentType::kNeighbourhood) e << YAML::Key << "k" << YAML::Value << x.k;
    switch (x.type) {
      case ExperimentType::kNeighbourhood:
        e << YAML::Key << "k_values" << YAML::Value << YAML::Flow << x.k_values;
        e << YAML::Key << "pose" << YAML::Value;
        emit_pose(e, x.pose, {});
        break;
      case ExperimentType::kYaw:
        e << YAML::Key << "yaw_deg" << YAML::Value;
        emit_numbers(e, x.yaw_deg);
        e << YAML::Key << "pose" << YAML::Value;
        emit_pose(e, x.pose, {"yaw_deg"});
        break;
      case ExperimentType::kXy:
        if (x.escalate) {
          e << YAML::Key << "escalate" << YAML::Value << YAML::Flow << YAML::BeginMap;
          e << YAML::Key << "start_m" << YAML::Value;
          emit_number(e, x.escalation.start_m);
          e << YAML::Key << "step_m" << YAML::Value;
          emit_number(e, x.escalation.step_m);
          e << YAML::Key << "max_m" << YAML::Value;
          emit_number(e, x.escalation.max_m);
          e << YAML::Key << "stop" << YAML::Value
            << (x.escalation.stop_when_all_fail ? "all" : "any");
          e << YAML::EndMap;
          e << YAML::Key << "quadrants" << YAML::Value;
          emit_quadrants(e, x.quadrants);
        } else {
          e << YAML::Key << "offsets_m" << YAML::Value << YAML::BeginMap;
          for (const auto& [q, offsets] : x.offsets_m) {
            e << YAML::Key << q.name() << YAML::Value;
            emit_numbers(e, offsets);
          }
          e << YAML::EndMap;
        }
        e << YAML::Key << "pose" << YAML::Value;
        emit_pose(e, x.pose, {"x_m", "y_m"});
        break;
      case ExperimentType::kXyYaw:
        e << YAML::Key << "offset_m" << YAML::Value;
        emit_number(e, x.offset_m);
        e << YAML::Key << "yaw_deg" << YAML::Value;
        emit_numbers(e, x.yaw_deg);
        e << YAML::Key << "quadrants" << YAML::Value;
        emit_quadrants(e, x.quadrants);
        e << YAML::Key << "pose" << YAML::Value;
        emit_pose(e, x.pose, {"x_m", "y_m", "yaw_deg"});
        break;
      case ExperimentType::kPoses:
        e << YAML::Key << "poses" << YAML::Value << YAML::BeginSeq;
        for (const Pose6& p : x.poses) emit_pose(e, p, {});
        e << YAML::EndSeq;
        break;
      case ExperimentType::kBasin:
        e << YAML::Key << "levels" << YAML::Value << YAML::BeginMap;
        if (!x.basin.yaw_levels_deg.empty()) {
          e << YAML::Key << "yaw_deg" << YAML::Value;
          emit_numbers(e, x.basin.yaw_levels_deg);
        }
        if (!x.basin.translation_levels_m.empty()) {
          e << YAML::Key << "translation_m" << YAML::Value;
          emit_numbers(e, x.basin.translation_levels_m);
        }
        e << YAML::EndMap;
        e << YAML::Key << "samples" << YAML::Value << x.basin.samples;
        e << YAML::Key << "seed" << YAML::Value << std::to_string(x.basin.seed);
        e << YAML::Key << "yaw_pivot" << YAML::Value << to_string(x.basin.yaw_pivot);
        e << YAML::Key << "translation_directions" << YAML::Value
          << to_string(x.basin.translation_directions);
        break;
      case ExperimentType::kRandom:
        e << YAML::Key << "samples" << YAML::Value << x.random.samples;
        e << YAML::Key << "seed" << YAML::Value << std::to_string(x.random.seed);
        e << YAML::Key << "yaw_deg" << YAML::Value;
        emit_number(e, x.random.yaw_deg);
        e << YAML::Key << "translation_m" << YAML::Value;
        emit_number(e, x.random.translation_m);
        e << YAML::Key << "roll_pitch_deg" << YAML::Value;
        emit_number(e, x.random.roll_pitch_deg);
        e << YAML::Key << "pivot" << YAML::Value << to_string(x.random.pivot);
        e << YAML::Key << "up_axis" << YAML::Value << to_string(x.random.up_axis);
        break;
    }
    e << YAML::EndMap;
  }
  e << YAML::EndSeq;
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
