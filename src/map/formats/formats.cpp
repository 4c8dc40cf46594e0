// Format detection, the dispatching reader and writer, and derived confidences
// (include/lmalign/map/formats/formats.hpp, docs/map-format.md "Other formats").
#include "lmalign/map/formats/formats.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/map/formats/bundler.hpp"
#include "lmalign/map/formats/colmap.hpp"
#include "lmalign/map/formats/ply.hpp"
#include "lmalign/map/formats/stella_vslam.hpp"
#include "lmalign/map/formats/xyz.hpp"
#include "lmalign/map/triangulation.hpp"

namespace lmalign {

namespace {

bool has_files(const std::filesystem::path& dir, const char* ext) {
  for (const char* stem : {"cameras", "images", "points3D"}) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(dir / (std::string(stem) + ext), ec)) return false;
  }
  return true;
}

// Detectors: each looks at the probe only.
bool is_ours(const MapProbe& p) {
  if (p.is_directory) return false;
  const std::string_view record(p.first_record);
  for (const char* type : {"FRAME", "LANDMARK", "MAP"}) {
    const std::size_t len = std::char_traits<char>::length(type);
    if (record.substr(0, len) == type &&
        (record.size() == len || record[len] == ' ' || record[len] == '\t')) {
      return true;
    }
  }
  return false;
}
bool is_bundler(const MapProbe& p) {
  return !p.is_directory && p.first_line == "# Bundle file v0.3";
}
bool is_colmap_text(const MapProbe& p) {
  return p.is_directory && has_files(p.path, ".txt") && !has_files(p.path, ".bin");
}
bool is_colmap_binary(const MapProbe& p) { return p.is_directory && has_files(p.path, ".bin"); }
bool is_ply(const MapProbe& p) { return !p.is_directory && p.first_line == "ply"; }
bool is_stella_vslam(const MapProbe& p) {
  // A MessagePack map (fixmap, map 16 or map 32) whose first key, in nlohmann's sorted order, is
  // the 7-byte string "cameras" (fixstr 0xa7).
  const std::string_view bytes(p.head);
  const auto first = bytes.empty() ? 0 : static_cast<unsigned char>(bytes[0]);
  const std::size_t key_at = (first >= 0x80 && first <= 0x8f) ? 1
                             : first == 0xde                  ? 3
                             : first == 0xdf                  ? 5
                                                              : 0;
  return !p.is_directory && key_at > 0 &&
         bytes.substr(key_at, 8) == std::string_view(
                                        "\xa7"
                                        "cameras",
                                        8);
}
bool is_xyz(const MapProbe& p) {
  return !p.is_directory && !p.first_record.empty() && is_xyz_record(p.first_record);
}

// Readers: the format's own reader with the options that apply to it.
Map read_ours(const std::string& path, const AnyMapReadOptions& o, MapFileExtras* extras) {
  return read_map(path, o.map, &extras->dropped_min_observations);
}
Map read_bundler_file(const std::string& path, const AnyMapReadOptions& o, MapFileExtras*) {
  BundlerReadOptions bo;
  if (o.image_size_px) {
    bo.width_px = (*o.image_size_px)[0];
    bo.height_px = (*o.image_size_px)[1];
  }
  return read_bundler(path, bo);
}
Map read_colmap_model(const std::string& path, const AnyMapReadOptions& o, MapFileExtras* extras,
                      bool binary) {
  ColmapReadOptions co;
  co.quaternion_norm_tolerance = o.map.quaternion_norm_tolerance;
  return read_colmap(path, binary, co, &extras->sigma_px);
}
Map read_colmap_text(const std::string& path, const AnyMapReadOptions& o, MapFileExtras* extras) {
  return read_colmap_model(path, o, extras, false);
}
Map read_colmap_binary(const std::string& path, const AnyMapReadOptions& o, MapFileExtras* extras) {
  return read_colmap_model(path, o, extras, true);
}
Map read_ply_file(const std::string& path, const AnyMapReadOptions&, MapFileExtras* extras) {
  PlyReadReport report;
  Map map = read_ply_map(path, &report);
  if (extras != nullptr) {
    extras->camera_centres_left_out = report.camera_centres_left_out;
    extras->camera_centres_rule = report.camera_centres_rule;
  }
  return map;
}
Map read_stella_file(const std::string& path, const AnyMapReadOptions&, MapFileExtras*) {
  return read_stella_vslam(path);
}
Map read_xyz_file(const std::string& path, const AnyMapReadOptions&, MapFileExtras*) {
  return read_xyz_map(path);
}
void write_colmap_model(const std::string& path, const Map& map) { write_colmap_text(path, map); }

}  // namespace

const std::vector<MapFormatInfo>& map_formats() {
  static const std::vector<MapFormatInfo> rows{
      {MapFormat::kLmalign, "lmalign", "our map text format (MAP, FRAME and LANDMARK records)",
       "an lmalign map (MAP / FRAME / LANDMARK records)", MapFormatKind::kOurs, is_ours, read_ours,
       write_map},
      {MapFormat::kBundler, "bundler", "Bundler v0.3 .out (cameras, points, their views)",
       "Bundler v0.3 (first line '# Bundle file v0.3')", MapFormatKind::kReconstruction, is_bundler,
       read_bundler_file, nullptr},
      {MapFormat::kColmapText, "colmap-text",
       "a COLMAP sparse model folder of cameras.txt, images.txt, points3D.txt",
       "a COLMAP text model (a folder of cameras.txt, images.txt, points3D.txt)",
       MapFormatKind::kReconstruction, is_colmap_text, read_colmap_text, write_colmap_model},
      {MapFormat::kColmapBinary, "colmap-bin",
       "a COLMAP sparse model folder of cameras.bin, images.bin, points3D.bin",
       "a COLMAP binary model (a folder of cameras.bin, images.bin, points3D.bin)",
       MapFormatKind::kReconstruction, is_colmap_binary, read_colmap_binary, nullptr},
      {MapFormat::kPly, "ply", "a PLY point cloud, with or without covariance properties",
       "PLY (first line 'ply')", MapFormatKind::kPointCloud, is_ply, read_ply_file, write_ply_map},
      {MapFormat::kStellaVslam, "stella-vslam", "a stella_vslam / OpenVSLAM map database (.msg)",
       "a stella_vslam map database (a MessagePack map whose first key is 'cameras')",
       MapFormatKind::kReconstruction, is_stella_vslam, read_stella_file, nullptr},
      {MapFormat::kXyz, "xyz", "XYZ text: one point 'x y z' per line",
       "XYZ text (a point 'x y z' per line)", MapFormatKind::kPointCloud, is_xyz, read_xyz_file,
       nullptr},
  };
  return rows;
}

const MapFormatInfo& map_format_info(MapFormat format) {
  for (const MapFormatInfo& f : map_formats()) {
    if (f.format == format) return f;
  }
  throw InvalidArgument("map format 'auto' has no reader of its own (detect_map_format)");
}

std::string map_format_names() {
  std::string out = "auto";
  for (const MapFormatInfo& f : map_formats()) out += ", " + std::string(f.name);
  return out;
}

std::string map_format_name(MapFormat format) {
  for (const MapFormatInfo& f : map_formats()) {
    if (f.format == format) return f.name;
  }
  return "auto";
}

MapFormat parse_map_format(const std::string& name) {
  if (name == "auto") return MapFormat::kAuto;
  for (const MapFormatInfo& f : map_formats()) {
    if (name == f.name) return f.format;
  }
  throw InvalidArgument("map format '" + name + "' is not one of: " + map_format_names());
}

MapFormat detect_map_format(const std::string& path) {
  MapProbe probe;
  probe.path = path;
  std::error_code ec;
  probe.is_directory = std::filesystem::is_directory(path, ec);
  if (!probe.is_directory) {
    errno = 0;
    std::ifstream in(path, std::ios::binary);
    if (!in) {  // the same message as read_map's
      throw IoError("cannot open map file '" + path +
                    "': " + std::strerror(errno != 0 ? errno : ENOENT));
    }
    char head[16] = {};
    in.read(head, sizeof(head));
    probe.head.assign(head, static_cast<std::size_t>(in.gcount()));
    in.clear();
    in.seekg(0);
    // The first line, and the first non-blank, non-comment line (at most 4 KiB of each).
    std::string line;
    bool first = true;
    while (in) {
      line.clear();
      char c = 0;
      while (in.get(c) && c != '\n') {
        if (line.size() < 4096) line.push_back(c);
      }
      if (in.bad()) throw IoError("cannot read map file '" + path + "'");
      if (!line.empty() && line.back() == '\r') line.pop_back();
      if (first) probe.first_line = line;
      first = false;
      const std::size_t start = line.find_first_not_of(" \t");
      if (start != std::string::npos && line[start] != '#') {
        probe.first_record = line.substr(start);
        break;
      }
    }
  }
  for (const MapFormatInfo& f : map_formats()) {
    if (f.detect(probe)) return f.format;
  }
  // A file of only blank and comment lines: an empty map of ours (read_any_map refuses it).
  if (!probe.is_directory && probe.first_record.empty()) return MapFormat::kLmalign;
  std::string looked_for;
  for (const MapFormatInfo& f : map_formats()) {
    looked_for += (looked_for.empty() ? "not " : ", not ") + std::string(f.detected_by);
  }
  throw InvalidArgument("cannot tell the format of " +
                        std::string(probe.is_directory ? "the folder '" : "'") + path +
                        "': " + looked_for + "; use --format to choose a reader");
}

bool ConfidenceOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!std::isfinite(pixel_sigma_px) || pixel_sigma_px < 0.0) {
    return fail("pixel_sigma_px (" + std::to_string(pixel_sigma_px) +
                ") must be finite and >= 0 (0: the default)");
  }
  if (!(min_parallax_deg >= 0.0 && min_parallax_deg <= 180.0)) {
    return fail("min_parallax_deg (" + std::to_string(min_parallax_deg) + ") must be in [0, 180]");
  }
  if (max_iterations < 0) return fail("max_iterations must be >= 0");
  return true;
}

std::size_t estimate_covariances(Map& map, const ConfidenceOptions& options,
                                 const std::vector<double>* sigma_px_per_landmark,
                                 const PinholeIntrinsics& fallback,
                                 std::vector<CovarianceEstimate>* estimates) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("confidence options: " + why);
  if (sigma_px_per_landmark != nullptr && sigma_px_per_landmark->size() != map.landmarks.size()) {
    throw InvalidArgument("estimate_covariances: sigma_px_per_landmark has " +
                          std::to_string(sigma_px_per_landmark->size()) + " entries for " +
                          std::to_string(map.landmarks.size()) + " landmarks");
  }
  std::unordered_map<Id, std::size_t> frame_at;
  for (std::size_t i = 0; i < map.frames.size(); ++i) frame_at.emplace(map.frames[i].id, i);
  std::vector<Isometry3> poses;
  poses.reserve(map.frames.size());
  for (const Frame& frame : map.frames) poses.push_back(frame.T_world_camera());

  std::size_t flagged = 0;
  std::vector<PixelView> views;
  if (estimates != nullptr) estimates->assign(map.landmarks.size(), CovarianceEstimate{});
  for (std::size_t l = 0; l < map.landmarks.size(); ++l) {
    Landmark& landmark = map.landmarks[l];
    views.clear();
    for (const Observation& obs : landmark.observations) {
      const auto it = frame_at.find(obs.frame_id);
      if (it == frame_at.end()) {
        throw InvalidArgument("landmark " + std::to_string(landmark.id) +
                              " observes unknown frame " + std::to_string(obs.frame_id));
      }
      const std::optional<PixelView> view =
          make_pixel_view(poses[it->second], map.frames[it->second].camera, obs.u_px, obs.v_px);
      if (view) views.push_back(*view);  // else not a usable view
    }
    TriangulationOptions topt;
    topt.intrinsics = fallback;
    topt.max_iterations = options.max_iterations;
    topt.pixel_sigma_px = options.pixel_sigma_px > 0.0 ? options.pixel_sigma_px : 1.0;
    if (options.pixel_sigma_px == 0.0 && sigma_px_per_landmark != nullptr &&
        (*sigma_px_per_landmark)[l] > 0.0 && std::isfinite((*sigma_px_per_landmark)[l])) {
      topt.pixel_sigma_px = (*sigma_px_per_landmark)[l];
    }
    const std::optional<TriangulatedPoint> point =
        views.size() >= 2 ? triangulate(views, topt) : std::nullopt;
    using Kind = CovarianceEstimate::Kind;
    CovarianceEstimate estimate;
    estimate.kind = views.size() < 2 ? Kind::kTooFewViews : Kind::kNotTriangulated;
    if (point) {
      estimate.max_parallax_deg = point->max_parallax_deg;
      estimate.kind = point->max_parallax_deg >= options.min_parallax_deg ? Kind::kTriangulated
                                                                          : Kind::kBelowMinParallax;
    }
    if (estimate.kind == Kind::kTriangulated) {
      landmark.cov_world_m2 = point->cov_world_m2;
      landmark.covariance_unknown = false;
    } else {
      landmark.cov_world_m2 = Mat3::Zero();
      landmark.covariance_unknown = true;
      ++flagged;
    }
    if (estimates != nullptr) (*estimates)[l] = estimate;
  }
  return flagged;
}

namespace {

[[noreturn]] void refuse_empty(const std::string& path, MapFormat format, const Map& map) {
  throw InvalidArgument("map '" + path + "' has no landmarks (" + map_format_name(format) + ": " +
                        std::to_string(map.frames.size()) +
                        " frames, 0 landmarks); there is nothing to align");
}

/// Refuses a file of 3 or more landmarks that all lie at one point or on one line: no rigid
/// transform can be estimated from it. (One or two landmarks are left to the alignment, which
/// reports them as for our own format.)
void refuse_degenerate(const std::string& path, const Map& map) {
  const std::size_t n = map.landmarks.size();
  if (n < 3) return;
  Vec3 mean = Vec3::Zero();
  for (const Landmark& l : map.landmarks) mean += l.p_world;
  mean /= static_cast<double>(n);
  Mat3 scatter = Mat3::Zero();
  double largest_coordinate = 0.0;
  for (const Landmark& l : map.landmarks) {
    const Vec3 d = l.p_world - mean;
    scatter += d * d.transpose();
    largest_coordinate = std::max(largest_coordinate, l.p_world.cwiseAbs().maxCoeff());
  }
  scatter /= static_cast<double>(n);
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(scatter, Eigen::EigenvaluesOnly);
  const Vec3 spread = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();  // ascending, metres
  if (!(spread(2) > 1e-12 * std::max(1.0, largest_coordinate))) {
    throw InvalidArgument("map '" + path + "': its " + std::to_string(n) +
                          " landmark(s) all lie at one point; there is nothing to align");
  }
  if (!(spread(1) > 1e-6 * spread(2))) {
    throw InvalidArgument("map '" + path + "': its " + std::to_string(n) +
                          " landmarks all lie on one line (spread across it " +
                          std::to_string(spread(1)) + ", along it " + std::to_string(spread(2)) +
                          "); no rotation about that line can be estimated");
  }
}

}  // namespace

Map read_any_map(const std::string& path, const AnyMapReadOptions& options,
                 MapReadStats* stats_out) {
  const MapFormat format =
      options.format == MapFormat::kAuto ? detect_map_format(path) : options.format;
  const MapFormatInfo& info = map_format_info(format);
  MapReadStats stats;
  MapFileExtras extras;
  if (info.kind == MapFormatKind::kOurs) {
    Map map = info.read(path, options, &extras);
    const std::size_t dropped = extras.dropped_min_observations;
    // Empty file, or every landmark below min_observations (the caller's to report)?
    if (map.landmarks.empty() && dropped == 0) refuse_empty(path, format, map);
    stats.landmarks_in_file = map.landmarks.size() + dropped;
    stats.kept_stored = map.landmarks.size();
    stats.dropped_min_observations = dropped;
    if (stats_out != nullptr) *stats_out = stats;
    return map;
  }
  std::string why;
  if (!options.map.is_valid(&why)) throw InvalidArgument("map read options: " + why);
  if (!options.confidence.is_valid(&why)) throw InvalidArgument("confidence options: " + why);

  Map map = info.read(path, options, &extras);
  if (info.kind == MapFormatKind::kPointCloud) {
    // Point clouds: no observations, so min_observations does not apply.
    if (map.landmarks.empty()) refuse_empty(path, format, map);
    refuse_degenerate(path, map);
    stats.landmarks_in_file = map.landmarks.size();
    stats.camera_centres_left_out = extras.camera_centres_left_out;
    stats.camera_centres_rule = extras.camera_centres_rule;
    const bool any_known = std::any_of(map.landmarks.begin(), map.landmarks.end(),
                                       [](const Landmark& l) { return !l.covariance_unknown; });
    if (!any_known) {
      if (options.keep_unknown_covariance) {
        stats.kept_unknown = map.landmarks.size();
      } else {
        try {
          assume_covariances_from_spacing(map);
        } catch (const InvalidArgument& e) {
          throw InvalidArgument("map '" + path + "': " + e.what());
        }
        stats.kept_assumed = map.landmarks.size();
      }
    } else {
      for (const Landmark& l : map.landmarks) {
        if (!l.covariance_unknown) {
          ++stats.kept_stored;
        } else if (options.keep_unknown_covariance) {
          ++stats.kept_unknown;
        } else {
          ++stats.dropped_unknown;
        }
      }
      if (!options.keep_unknown_covariance) {
        map.landmarks.erase(std::remove_if(map.landmarks.begin(), map.landmarks.end(),
                                           [](const Landmark& l) { return l.covariance_unknown; }),
                            map.landmarks.end());
      }
    }
    map.validate();
    if (stats_out != nullptr) *stats_out = stats;
    return map;
  }
  const std::vector<double>& sigma_px = extras.sigma_px;
  if (map.landmarks.empty()) refuse_empty(path, format, map);
  refuse_degenerate(path, map);
  std::vector<CovarianceEstimate> estimates;
  estimate_covariances(map, options.confidence, sigma_px.empty() ? nullptr : &sigma_px,
                       PinholeIntrinsics::tum_fr1(), &estimates);
  stats.landmarks_in_file = map.landmarks.size();
  const std::size_t min_obs = options.map.min_observations;
  const bool keep_unknown = options.keep_unknown_covariance;
  std::vector<bool> keep(map.landmarks.size(), true);
  using Kind = CovarianceEstimate::Kind;
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    const CovarianceEstimate& e = estimates[i];
    if (map.landmarks[i].observations.size() < min_obs) {
      ++stats.dropped_min_observations;
      keep[i] = false;
    } else if (e.kind == Kind::kTriangulated) {
      ++(e.max_parallax_deg < kLowParallaxDeg ? stats.kept_low_parallax : stats.kept_triangulated);
    } else if (keep_unknown) {
      ++stats.kept_unknown;
    } else {
      keep[i] = false;
      ++(e.kind == Kind::kTooFewViews        ? stats.dropped_too_few_views
         : e.kind == Kind::kBelowMinParallax ? stats.dropped_below_min_parallax
                                             : stats.dropped_not_triangulated);
    }
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    if (keep[i]) {
      if (kept != i) map.landmarks[kept] = std::move(map.landmarks[i]);
      ++kept;
    }
  }
  map.landmarks.resize(kept);
  map.validate();
  if (stats_out != nullptr) *stats_out = stats;
  return map;
}

bool writes_colmap_text(const std::string& path) {
  std::error_code ec;
  return (!path.empty() && path.back() == '/') || std::filesystem::is_directory(path, ec);
}

std::string written_map_format_names() {
  std::string names;
  for (const MapFormatInfo& f : map_formats()) {
    if (f.write != nullptr) names += (names.empty() ? "" : ", ") + std::string(f.name);
  }
  return names;
}

MapFormat written_map_format(const std::string& path, MapFormat format) {
  if (format != MapFormat::kAuto) {
    if (map_format_info(format).write == nullptr) {
      throw InvalidArgument(std::string("lmalign does not write the format '") +
                            map_format_info(format).name + "' (it writes " +
                            written_map_format_names() + ")");
    }
    return format;
  }
  if (writes_colmap_text(path)) return MapFormat::kColmapText;
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".ply" ? MapFormat::kPly : MapFormat::kLmalign;
}

void check_map_writable(const std::string& path, const Map& map, MapFormat format) {
  const MapFormat f = written_map_format(path, format);
  if (f != MapFormat::kLmalign && f != MapFormat::kColmapText) return;
  for (const Frame& frame : map.frames) {
    if (frame.camera && frame.camera->centred_pixels) {
      throw InvalidArgument(
          "FRAME " + std::to_string(frame.id) +
          ": its pixels are relative to the image centre (a Bundler map read without an image "
          "size); " +
          (f == MapFormat::kColmapText ? "COLMAP" : "the map text format") +
          " stores pixels from the top-left corner: give the image size (--image-size W,H)");
    }
  }
}

void write_any_map(const std::string& path, const Map& map, MapFormat format) {
  map_format_info(written_map_format(path, format)).write(path, map);
}

}  // namespace lmalign
