// Reading and writing the map text file (method.md §1; format in docs/map-format.md).
//
//   MAP scale metric|arbitrary|unknown covariance estimated|assumed   (optional, at most once)
//   FRAME id tx ty tz qw qx qy qz
//   LANDMARK id x y z c00 c01 c02 c10 c11 c12 c20 c21 c22 n  f_1 u_1 v_1 ... f_n u_n v_n
//
// FRAME: T_world_camera, translation = camera centre (m), quaternion scalar-first (w x y z).
// LANDMARK: world position (m), row-major 3x3 covariance (m^2), n observations (frame id, u, v px).
// Blank lines and lines starting with '#' are ignored; CRLF line endings are accepted.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <string>

#include "lmalign/map/map.hpp"

namespace lmalign {

struct MapReadOptions {
  /// Landmarks with fewer observations are dropped after validation (the paper's loader keeps
  /// n >= 2). 0 keeps every landmark.
  std::size_t min_observations = 2;
  /// Largest accepted | |q| - 1 | for a FRAME quaternion.
  double quaternion_norm_tolerance = 1e-3;
  /// Covariance symmetry tolerance: |c_ij - c_ji| <= tol * max(1e-12, max|c|).
  double covariance_symmetry_tolerance = 1e-6;
  /// PSD tolerance: smallest eigenvalue >= -tol * max(1e-12, largest |eigenvalue|).
  double covariance_psd_tolerance = 1e-9;
  /// Longest accepted line, in bytes (without its line ending). A longer line throws ParseError
  /// naming it, after reading at most this many bytes of it, so one endless line cannot exhaust
  /// memory. 1 MiB holds a LANDMARK with about 40,000 observations (docs/robustness.md).
  std::size_t max_line_bytes = std::size_t{1} << 20;

  /// Ceres-style check: false, and *why names the bad field (tolerances must be finite and
  /// >= 0; max_line_bytes >= 64). read_map throws InvalidArgument on invalid options.
  bool is_valid(std::string* why = nullptr) const;
};

/// Reads a map file. The MAP record, if any, fills Map::header (else the default: metric,
/// estimated covariances). Strict: every malformed record throws ParseError naming the file, the
/// 1-based line and what was expected (unknown record type, a bad or repeated MAP record or key,
/// missing or extra token, non-numeric
/// value, NaN/inf, quaternion norm off by more than the tolerance, non-symmetric or non-PSD
/// covariance, observation of an unknown frame, duplicate frame or landmark id).
/// Throws IoError if the file cannot be opened or read, InvalidArgument if options are invalid.
/// Memory: the text is streamed one line at a time; only the kept landmarks, and the ids and
/// line numbers of all records, are held. `num_dropped`, if given, receives the number of
/// landmarks dropped by options.min_observations.
Map read_map(const std::string& path, const MapReadOptions& options = {},
             std::size_t* num_dropped = nullptr);

/// Same, from a stream; `name` is used in error messages in place of a path.
Map read_map(std::istream& in, const std::string& name, const MapReadOptions& options = {},
             std::size_t* num_dropped = nullptr);

/// Writes `map` atomically (temporary file in the same directory, then rename). Values are written
/// in the shortest form that reads back to the same double, so write -> read is exact.
/// Throws IoError (nothing is left at `path` on failure) or InvalidArgument if map.validate() fails
/// or the map holds something read_map (default options) would reject: a quaternion whose norm is
/// off by more than 1e-3, a covariance that is not symmetric or not positive semi-definite, or a
/// landmark flagged covariance_unknown (the format has no way to say so), or a frame whose
/// camera has centred_pixels (the format stores pixels from the top-left corner). Frame
/// intrinsics (Frame::camera) are not written: the format has none. The header is written as a
/// MAP record, first, when it is not the default, so default maps are written as before.
void write_map(const std::string& path, const Map& map);

/// Writes the map text to a stream (no validation, no atomicity).
void write_map(std::ostream& out, const Map& map);

}  // namespace lmalign
