// Reading maps written by other tools into the Map model, and choosing the reader by content
// (docs/map-format.md, "Other formats"). Our own text format (map_io.hpp) stays the reference.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

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
  kXyz,           ///< XYZ text point cloud, one point per line (formats/xyz.hpp)
};

/// The name used by `--format` (map_formats()' names, and "auto").
std::string map_format_name(MapFormat format);
/// Parses a `--format` name. Throws InvalidArgument listing the accepted names
/// (map_format_names()).
MapFormat parse_map_format(const std::string& name);

/// The format of `path`, by content: the first row of map_formats() whose detect() accepts it
/// (a folder is a COLMAP model, binary if it holds cameras.bin, images.bin and points3D.bin,
/// else text if it holds the three .txt files; a file whose first line is "# Bundle file v0.3"
/// is Bundler, one whose first line is "ply" is PLY, one that starts with a MessagePack map
/// whose first key is "cameras" is a stella_vslam map database; a file whose first record
/// (after blank and comment lines) starts with MAP, FRAME or LANDMARK is ours, one whose first
/// record is 3 or more numbers is XYZ text); a file that holds no record is ours (an empty map).
/// Throws IoError if `path` cannot be read, InvalidArgument naming the path and what each
/// format is detected by if it is none of them.
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
  /// map can be aligned and written in our format, and point clouds without covariances get
  /// them assumed from the spacing. true: they are kept, flagged (point clouds as read).
  bool keep_unknown_covariance = false;
};

/// What estimate_covariances() found for one landmark.
struct CovarianceEstimate {
  enum class Kind {
    kTriangulated,      ///< covariance set (parallax >= min_parallax_deg)
    kBelowMinParallax,  ///< triangulated, but parallax below min_parallax_deg: flagged
    kTooFewViews,       ///< fewer than 2 usable views: cannot be triangulated; flagged
    kNotTriangulated,   ///< triangulation failed (no parallax, behind a camera, ...); flagged
  };
  Kind kind = Kind::kNotTriangulated;
  /// Largest angle between two viewing rays, degrees (0 unless triangulated).
  double max_parallax_deg = 0.0;
};

/// Re-estimates the covariance of every landmark of `map` from its observations and the frames'
/// poses and intrinsics, by triangulate() (triangulation.hpp, as `split --retriangulate`):
/// distorted pixels are first undistorted (CameraIntrinsics::undistort_px) and the covariance is
/// (J^T J)^-1 sigma^2 of the pinhole reprojection error at the triangulated point. The stored
/// position is kept. A landmark with fewer than 2 usable views, a failed triangulation or a
/// parallax below options.min_parallax_deg gets covariance_unknown = true and a zero covariance.
/// `sigma_px_per_landmark`, if given (one per landmark, 0 = none), overrides the default noise
/// when options.pixel_sigma_px is 0. Frames without intrinsics use `fallback` (the TUM fr1
/// pinhole by default). `estimates`, if given, receives one CovarianceEstimate per landmark.
/// Returns the number of landmarks flagged.
/// Throws InvalidArgument on invalid options, a sigma vector of the wrong size, or an
/// observation of a frame missing from the map.
std::size_t estimate_covariances(Map& map, const ConfidenceOptions& options,
                                 const std::vector<double>* sigma_px_per_landmark = nullptr,
                                 const PinholeIntrinsics& fallback = PinholeIntrinsics::tum_fr1(),
                                 std::vector<CovarianceEstimate>* estimates = nullptr);

/// Below this parallax (degrees) a triangulated landmark counts as low-parallax in MapReadStats:
/// its covariance is large along the viewing direction, but well defined.
inline constexpr double kLowParallaxDeg = 1.0;

/// What read_any_map() did with the landmarks of a file, by kind (`convert` prints it). Every
/// landmark of the file is counted once: landmarks_in_file = kept() + dropped().
struct MapReadStats {
  std::size_t landmarks_in_file = 0;
  // Kept, by where their covariance comes from:
  std::size_t kept_stored = 0;        ///< stored in the file (ours, a PLY with covariances)
  std::size_t kept_triangulated = 0;  ///< triangulated, parallax >= kLowParallaxDeg
  std::size_t kept_low_parallax = 0;  ///< triangulated, parallax below kLowParallaxDeg
  std::size_t kept_assumed = 0;       ///< assumed from the spacing (a point cloud without any)
  std::size_t kept_unknown = 0;       ///< unknown, flagged (keep_unknown_covariance)
  // Dropped:
  std::size_t dropped_min_observations = 0;    ///< fewer than map.min_observations
  std::size_t dropped_too_few_views = 0;       ///< fewer than 2 usable views
  std::size_t dropped_not_triangulated = 0;    ///< triangulation failed
  std::size_t dropped_below_min_parallax = 0;  ///< parallax below confidence.min_parallax_deg
  std::size_t dropped_unknown = 0;             ///< a PLY vertex flagged covariance_known = 0
  // Not landmarks, so not in landmarks_in_file: OpenMVG's camera centres, which OpenMVG writes
  // into its PLYs as pure green vertices (read_ply_map, formats/ply.hpp), and how they were
  // recognised (PlyReadReport::camera_centres_rule; "" when none).
  std::size_t camera_centres_left_out = 0;
  std::string camera_centres_rule;

  std::size_t kept() const {
    return kept_stored + kept_triangulated + kept_low_parallax + kept_assumed + kept_unknown;
  }
  std::size_t dropped() const {
    return dropped_min_observations + dropped_too_few_views + dropped_not_triangulated +
           dropped_below_min_parallax + dropped_unknown;
  }
};

/// Reads a map in any supported format (options.format, or detect_map_format()). For formats
/// without covariances they are derived by estimate_covariances(); then landmarks with fewer
/// than options.map.min_observations observations, and (unless keep_unknown_covariance) those
/// with an unknown covariance, are dropped. Point clouds (PLY, XYZ text) have no observations:
/// min_observations does not apply; one that stores no covariance at all gets them assumed from
/// the landmark spacing (assume_covariances_from_spacing(): isotropic, sigma half the median
/// distance to the 6 nearest landmarks; MapHeader::covariance_assumed), unless
/// keep_unknown_covariance is set, which keeps them unknown. `stats`, if given, receives what
/// was kept and dropped, by kind. Throws what the chosen reader throws (ParseError
/// with file:line or byte offset, IoError), and InvalidArgument for bad options, for a file with
/// no landmarks ("map '<path>' has no landmarks (...)"; our format: an empty file, not one whose
/// landmarks are all below min_observations), and, for the other formats, for a file of 3 or
/// more landmarks that all lie at one point or on one line (our format leaves that to the
/// alignment, which reports it as degenerate).
Map read_any_map(const std::string& path, const AnyMapReadOptions& options = {},
                 MapReadStats* stats = nullptr);

/// True if write_any_map() writes a COLMAP text model to `path`: it ends in '/' or is an
/// existing folder.
bool writes_colmap_text(const std::string& path);
/// The format write_any_map() writes to `path`: `format` when it is not kAuto (a format lmalign
/// writes, else InvalidArgument naming those it writes), else by the form of the path:
/// kColmapText (a folder), kPly (extension .ply, any case) or kLmalign (anything else, "-"
/// included).
MapFormat written_map_format(const std::string& path, MapFormat format = MapFormat::kAuto);
/// "lmalign, ply, colmap-text": the formats lmalign writes (rows with a writer).
std::string written_map_format_names();

/// Throws InvalidArgument when write_any_map(path, map, format) would refuse `map` for what it
/// holds: frames whose pixels are relative to the image centre (a Bundler map read without an
/// image size) in a format that stores pixels from the top-left corner (ours, COLMAP text; a PLY
/// stores no pixels). A front end asks before the work whose result it writes, so that such an
/// output fails at once (`lmalign align --aligned-out`).
void check_map_writable(const std::string& path, const Map& map,
                        MapFormat format = MapFormat::kAuto);

/// Writes `map` in written_map_format(path, format): a folder (ending in '/' or existing) gets a
/// COLMAP text model (write_colmap_text, formats/colmap.hpp), a `.ply` path a PLY with the
/// covariances as properties (write_ply_map, formats/ply.hpp), any other path our text format
/// (write_map; see there for what is refused). Each file goes through the one output writer
/// (io/output_file.hpp: "-" is the standard output, links are followed, FIFOs written in place).
void write_any_map(const std::string& path, const Map& map, MapFormat format = MapFormat::kAuto);

/// What detect_map_format() looks at, read once from a path.
struct MapProbe {
  std::string path;
  bool is_directory = false;
  /// Files: the first 16 bytes, the first line (without its end; at most 4 KiB of it), and the
  /// first record: the first line that is neither blank nor a comment ('#'), from its first
  /// non-blank character ("" if the file holds none).
  std::string head;
  std::string first_line;
  std::string first_record;
};

/// Where read_any_map() takes a format's covariances from.
enum class MapFormatKind {
  kOurs,            ///< stored (our text format)
  kPointCloud,      ///< stored if any, else assumed from the spacing (no observations)
  kReconstruction,  ///< triangulated from the observations (estimate_covariances())
};

/// What a reader gives beside the map.
struct MapFileExtras {
  /// COLMAP: each landmark's mean reprojection error, pixels (0 = none stored).
  std::vector<double> sigma_px;
  /// Our format: landmarks dropped for fewer than min_observations observations.
  std::size_t dropped_min_observations = 0;
  /// PLY: OpenMVG's camera centres left out (PlyReadReport).
  std::size_t camera_centres_left_out = 0;
  std::string camera_centres_rule;
};

/// One format: one row of map_formats(). Every list of formats (the CLI's help, Python's
/// map_formats() and read_map(), parse_map_format()'s and detect_map_format()'s errors) is read
/// from these rows.
struct MapFormatInfo {
  MapFormat format;
  const char* name;         ///< the `--format` name
  const char* doc;          ///< one line: what it is
  const char* detected_by;  ///< what detect() looks for, as the detection error names it
  MapFormatKind kind;
  /// True when the content is accepted by this format (the rows are tried in order).
  bool (*detect)(const MapProbe& probe);
  /// The format's reader (options: min_observations and the quaternion tolerance of ours and
  /// COLMAP, Bundler's image size). Throws what the reader throws.
  Map (*read)(const std::string& path, const AnyMapReadOptions& options, MapFileExtras* extras);
  /// Its writer (atomic), or nullptr if lmalign does not write it.
  void (*write)(const std::string& path, const Map& map);
};

/// Every format lmalign reads, in the order detection tries them (not "auto").
const std::vector<MapFormatInfo>& map_formats();
/// The row of `format`. Throws InvalidArgument for kAuto.
const MapFormatInfo& map_format_info(MapFormat format);
/// "auto, lmalign, bundler, ...": every name `--format` accepts.
std::string map_format_names();

}  // namespace lmalign
