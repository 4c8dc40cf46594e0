// Reading maps written by other tools into the Map model, and choosing the reader by content
// (docs/map-format.md, "Other formats"). Our own text format (map_io.hpp) stays the reference.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "lmalign/map/map.hpp"
#include "lmalign/map/map_io.hpp"

namespace lmalign {

enum class MapFormat {
  kAuto,          ///< detect_map_format() decides
  kLmalign,       ///< our map text file (map_io.hpp)
  kBundler,       ///< Bundler v0.3 `.out` (formats/bundler.hpp)
  kColmapText,    ///< COLMAP sparse model folder with cameras.txt, images.txt, points3D.txt
  kColmapBinary,  ///< COLMAP sparse model folder with cameras.bin, images.bin, points3D.bin
  kPly,           ///< PLY point cloud, optional per-vertex covariance (formats/ply.hpp)
  kStellaVslam,   ///< stella_vslam / OpenVSLAM map database .msg (formats/stella_vslam.hpp)
};

/// The name used by `--format`: auto, lmalign, bundler, colmap-text, colmap-bin, ply,
/// stella-vslam.
std::string map_format_name(MapFormat format);
/// Parses a `--format` name. Throws InvalidArgument listing the accepted names.
MapFormat parse_map_format(const std::string& name);

/// The format of `path`, by content: a folder is a COLMAP model (binary if it holds
/// cameras.bin, images.bin and points3D.bin, else text if it holds the three .txt files); a file
/// whose first line is "# Bundle file v0.3" is Bundler, one whose first line is "ply" is PLY, one
/// that starts with a MessagePack map whose first key is "cameras" is a stella_vslam map
/// database; a file whose first record (after blank and
/// comment lines) starts with FRAME or LANDMARK, or that holds no record, is ours.
/// Throws IoError if `path` cannot be read, InvalidArgument naming the path and the formats
/// looked for if it is none of them.
MapFormat detect_map_format(const std::string& path);

/// How confidences are derived for formats that store none (docs/map-format.md).
struct ConfidenceOptions {
  /// Pixel noise standard deviation for the re-estimated covariance, pixels. 0 (the default)
  /// means: COLMAP's per-point mean reprojection error where the model stores a positive one,
  /// else 1 px.
  double pixel_sigma_px = 0.0;
  /// Landmarks whose largest angle between two viewing rays is below this (degrees) get no
  /// covariance (Landmark::covariance_unknown); so do one-view landmarks and failed
  /// triangulations.
  double min_parallax_deg = 1.0;
  /// Gauss-Newton iterations of the triangulation (triangulation.hpp).
  int max_iterations = 20;

  /// False, and *why names the field, if pixel_sigma_px is negative or not finite,
  /// min_parallax_deg is outside [0, 180], or max_iterations < 0.
  bool is_valid(std::string* why = nullptr) const;
};

struct AnyMapReadOptions {
  AnyMapReadOptions() = default;
  /// Our format's options and the format (call sites: read_any_map(path, {ropt, format})).
  AnyMapReadOptions(const MapReadOptions& map_options, MapFormat map_format = MapFormat::kAuto)
      : map(map_options), format(map_format) {}

  /// Options of our own format. min_observations also filters landmarks of the other formats
  /// (after the confidences are derived, counting the file's observations).
  MapReadOptions map;
  MapFormat format = MapFormat::kAuto;
  /// Bundler: the image size (width, height) in pixels. Bundler's pixels are relative to the
  /// image centre; with the size they are moved to the top-left corner, without it they stay
  /// centred (CameraIntrinsics::centred_pixels), which triangulation does not mind but outputs
  /// that store top-left pixels (our map text format, COLMAP) refuse.
  std::optional<std::array<long long, 2>> image_size_px;
  ConfidenceOptions confidence;
  /// false (the default): landmarks whose covariance could not be estimated are dropped, so the
  /// map can be aligned and written in our format. true: they are kept, flagged.
  bool keep_unknown_covariance = false;
};

/// Re-estimates the covariance of every landmark of `map` from its observations and the frames'
/// poses and intrinsics, by triangulate() (triangulation.hpp, as `split --retriangulate`):
/// distorted pixels are first undistorted (CameraIntrinsics::undistort_px) and the covariance is
/// (J^T J)^-1 sigma^2 of the pinhole reprojection error at the triangulated point. The stored
/// position is kept. A landmark with fewer than 2 usable views, a failed triangulation or a
/// parallax below options.min_parallax_deg gets covariance_unknown = true and a zero covariance.
/// `sigma_px_per_landmark`, if given (one per landmark, 0 = none), overrides the default noise
/// when options.pixel_sigma_px is 0. Frames without intrinsics use `fallback` (the TUM fr1
/// pinhole by default). Returns the number of landmarks flagged.
/// Throws InvalidArgument on invalid options, a sigma vector of the wrong size, or an
/// observation of a frame missing from the map.
std::size_t estimate_covariances(Map& map, const ConfidenceOptions& options,
                                 const std::vector<double>* sigma_px_per_landmark = nullptr,
                                 const PinholeIntrinsics& fallback = PinholeIntrinsics::tum_fr1());

/// Reads a map in any supported format (options.format, or detect_map_format()). For formats
/// without covariances they are derived by estimate_covariances(); then landmarks with fewer
/// than options.map.min_observations observations, and (unless keep_unknown_covariance) those
/// with an unknown covariance, are dropped. PLY has no observations: min_observations does not
/// apply, and a PLY with no covariance properties is an InvalidArgument unless
/// keep_unknown_covariance is set. Throws what the chosen reader throws (ParseError
/// with file:line or byte offset, IoError), and InvalidArgument for bad options, for a file with
/// no landmarks ("map '<path>' has no landmarks (...)"; our format: an empty file, not one whose
/// landmarks are all below min_observations), and, for the other formats, for a file of 3 or
/// more landmarks that all lie at one point or on one line (our format leaves that to the
/// alignment, which reports it as degenerate).
Map read_any_map(const std::string& path, const AnyMapReadOptions& options = {});

/// True if write_any_map() writes a COLMAP text model to `path`: it ends in '/' or is an
/// existing folder.
bool writes_colmap_text(const std::string& path);
/// The format write_any_map() writes to `path`: kColmapText (a folder), kPly (extension .ply,
/// any case) or kLmalign (anything else).
MapFormat written_map_format(const std::string& path);

/// Writes `map` by the form of `path` (written_map_format): a folder (ending in '/' or existing)
/// gets a COLMAP text model (write_colmap_text, formats/colmap.hpp), a `.ply` path a PLY with
/// the covariances as properties (write_ply_map, formats/ply.hpp), any other path our text
/// format (write_map; see there for what is refused). Each file is written atomically.
void write_any_map(const std::string& path, const Map& map);

}  // namespace lmalign
