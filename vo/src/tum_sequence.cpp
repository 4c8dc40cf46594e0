// TUM RGB-D sequence folders and camera presets (include/lmalign/vo/tum_sequence.hpp).
#include "lmalign/vo/tum_sequence.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "lmalign/core/error.hpp"

namespace lmalign::vo {

namespace fs = std::filesystem;

namespace {

std::vector<std::string> split_ws(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream ss(line);
  std::string tok;
  while (ss >> tok) out.push_back(tok);
  return out;
}

bool parse_number(const std::string& token, double& v) {
  const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
  return r.ec == std::errc() && r.ptr == token.data() + token.size() && std::isfinite(v);
}

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const auto b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

}  // namespace

bool TumSequenceOptions::is_valid(std::string* why) const {
  if (!std::isfinite(max_difference_s) || max_difference_s < 0.0) {
    if (why)
      *why = "max_difference_s must be a finite number >= 0 (got " +
             std::to_string(max_difference_s) + ")";
    return false;
  }
  return true;
}

bool RgbdCamera::is_valid(std::string* why) const {
  if (!pinhole.is_valid(why)) return false;
  if (width_px <= 0 || height_px <= 0) {
    if (why)
      *why = "image size must be positive (got " + std::to_string(width_px) + "x" +
             std::to_string(height_px) + ")";
    return false;
  }
  if (!std::isfinite(depth_units_per_m) || depth_units_per_m <= 0.0) {
    if (why) *why = "depth_scale must be > 0 units per metre";
    return false;
  }
  return true;
}

std::vector<TimedFile> read_tum_file_list(const std::string& list_path, const std::string& folder) {
  std::ifstream in(list_path);
  if (!in) {
    throw IoError("cannot open TUM file list '" + list_path + "': " + std::strerror(errno));
  }
  std::vector<TimedFile> out;
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto toks = split_ws(line);
    if (toks.empty() || toks[0][0] == '#') continue;
    if (toks.size() != 2) {
      throw ParseError(
          list_path, line_no,
          "line has " + std::to_string(toks.size()) + " fields, expected 2 (timestamp filename)");
    }
    double t = 0.0;
    if (!parse_number(toks[0], t) || t < 0.0) {
      throw ParseError(list_path, line_no,
                       "bad timestamp '" + toks[0] + "': expected a finite number >= 0 (seconds)");
    }
    if (!out.empty() && t <= out.back().timestamp_s) {
      throw ParseError(list_path, line_no,
                       "timestamp " + toks[0] + " does not increase (previous line " +
                           std::to_string(out.back().line) + ")");
    }
    out.push_back({t, (fs::path(folder) / toks[1]).string(), line_no});
  }
  if (in.bad()) throw IoError("cannot read TUM file list '" + list_path + "'");
  return out;
}

std::vector<RgbdFrameRef> associate_rgbd(const std::vector<TimedFile>& rgb,
                                         const std::vector<TimedFile>& depth,
                                         double max_difference_s) {
  Trajectory a, b;
  for (const auto& f : rgb) a.push_back({f.timestamp_s, Isometry3::Identity()});
  for (const auto& f : depth) b.push_back({f.timestamp_s, Isometry3::Identity()});
  std::vector<RgbdFrameRef> out;
  for (const auto& p : associate_trajectories(a, b, max_difference_s)) {
    const auto& r = rgb[p.estimate_index];
    const auto& d = depth[p.ground_truth_index];
    out.push_back({r.timestamp_s, r.path, d.timestamp_s, d.path});
  }
  return out;
}

TumSequence load_tum_sequence(const std::string& folder, const TumSequenceOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument(why);
  if (!fs::is_directory(folder)) {
    throw IoError("TUM sequence folder '" + folder + "' does not exist or is not a folder");
  }
  TumSequence seq;
  seq.folder = folder;
  const auto rgb = read_tum_file_list((fs::path(folder) / "rgb.txt").string(), folder);
  const auto depth = read_tum_file_list((fs::path(folder) / "depth.txt").string(), folder);
  seq.frames = associate_rgbd(rgb, depth, options.max_difference_s);
  if (seq.frames.empty()) {
    throw InvalidArgument("TUM sequence '" + folder + "': no RGB image of rgb.txt (" +
                          std::to_string(rgb.size()) + ") has a depth image of depth.txt (" +
                          std::to_string(depth.size()) + ") within " +
                          std::to_string(options.max_difference_s) + " s");
  }
  const fs::path gt = fs::path(folder) / "groundtruth.txt";
  if (options.read_ground_truth && fs::exists(gt)) {
    seq.ground_truth_path = gt.string();
    seq.ground_truth = read_tum_trajectory(gt.string());
  }
  return seq;
}

RgbdCamera tum_camera_preset(const std::string& name) {
  RgbdCamera c;
  if (name == "fr1" || name == "tum_fr1") {
    c.pinhole = {517.3, 516.5, 318.6, 255.3};
  } else if (name == "fr2" || name == "tum_fr2") {
    c.pinhole = {520.9, 521.0, 325.1, 249.7};
  } else if (name == "fr3" || name == "tum_fr3") {
    c.pinhole = {535.4, 539.2, 320.1, 247.6};
  } else {
    throw InvalidArgument("unknown camera preset '" + name + "' (expected fr1, fr2 or fr3)");
  }
  return c;
}

RgbdCamera read_camera_yaml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError("cannot open camera file '" + path + "': " + std::strerror(errno));
  std::map<std::string, std::pair<double, std::size_t>> values;
  static const char* kKeys[] = {"fx", "fy", "cx", "cy", "width", "height", "depth_scale"};
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line = line.substr(0, hash);
    line = trim(line);
    if (line.empty() || line == "---" || line.rfind("%YAML", 0) == 0) continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) {
      throw ParseError(path, line_no, "expected 'key: value', got '" + line + "'");
    }
    const std::string key = trim(line.substr(0, colon));
    const std::string text = trim(line.substr(colon + 1));
    if (std::find(std::begin(kKeys), std::end(kKeys), key) == std::end(kKeys)) {
      throw ParseError(
          path, line_no,
          "unknown key '" + key + "' (expected fx, fy, cx, cy, width, height, depth_scale)");
    }
    double v = 0.0;
    if (!parse_number(text, v)) {
      throw ParseError(path, line_no,
                       "value of '" + key + "' is not a finite number: '" + text + "'");
    }
    if (auto [it, inserted] = values.emplace(key, std::make_pair(v, line_no)); !inserted) {
      throw ParseError(
          path, line_no,
          "duplicate key '" + key + "' (first on line " + std::to_string(it->second.second) + ")");
    }
  }
  for (const char* k : {"fx", "fy", "cx", "cy"}) {
    if (!values.count(k)) throw ParseError(path, 0, std::string("missing key '") + k + "'");
  }
  RgbdCamera c;
  c.pinhole = {values["fx"].first, values["fy"].first, values["cx"].first, values["cy"].first};
  auto integer = [&](const char* key, int& out) {
    if (!values.count(key)) return;
    const auto [v, l] = values[key];
    if (v != std::floor(v) || v <= 0 || v > 100000) {
      throw ParseError(path, l, std::string("'") + key + "' must be a positive integer");
    }
    out = static_cast<int>(v);
  };
  integer("width", c.width_px);
  integer("height", c.height_px);
  if (values.count("depth_scale")) c.depth_units_per_m = values["depth_scale"].first;
  std::string why;
  if (!c.is_valid(&why)) throw ParseError(path, 0, "invalid camera: " + why);
  return c;
}

}  // namespace lmalign::vo
