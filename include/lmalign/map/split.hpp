// Mini-map extraction by frame window (method.md §6, `lmalign split`).
#pragma once

#include <cstddef>
#include <string>

#include "lmalign/map/map.hpp"
#include "lmalign/map/triangulation.hpp"

namespace lmalign {

struct SplitOptions {
  /// Inclusive frame-id window [first_frame_id, last_frame_id].
  Id first_frame_id = 0;
  Id last_frame_id = 0;
  /// A landmark is kept if it has at least this many observations inside the window.
  std::size_t min_observations = 2;
  /// false: keep the stored position and covariance; only observations (and hence the observation
  /// count and mean observation distance) are restricted to the window.
  /// true: re-estimate each landmark from the window's observations alone (triangulate()).
  bool retriangulate = false;
  /// With retriangulate: drop landmarks whose largest viewing-ray angle is below this, degrees.
  double min_parallax_deg = 2.0;
  TriangulationOptions triangulation;

  /// Ceres-style check; names the bad field and its value in *why, e.g.
  /// "first_frame_id (120) > last_frame_id (5)". Requires first_frame_id >= 0, first <= last,
  /// min_observations >= 1 (>= 2 with retriangulate), min_parallax_deg in [0, 180], valid
  /// intrinsics, pixel_sigma_px finite and > 0, max_iterations >= 0.
  bool is_valid(std::string* why = nullptr) const;
};

struct SplitStats {
  std::size_t frames_kept = 0;
  std::size_t landmarks_kept = 0;
  /// Landmarks with no observation in the window (not part of the mini-map; not counted as
  /// dropped).
  std::size_t landmarks_outside_window = 0;
  /// Landmarks with 1 .. min_observations-1 observations in the window.
  std::size_t dropped_too_few_observations = 0;
  std::size_t dropped_low_parallax = 0;          ///< retriangulate only
  std::size_t dropped_triangulation_failed = 0;  ///< retriangulate only
};

/// Cuts the mini-map of frames [first, last]: those frames (in their original order, poses
/// unchanged), and the landmarks with at least min_observations observations among them
/// (observations outside the window are removed; the rest keep their order). Landmark ids are
/// preserved and the output stays in the input's world frame.
///   retriangulate = false: position and covariance are copied bit for bit. The observation
///     count and mean observation distance, being derived from the observations, are the window's.
///   retriangulate = true: position and covariance come from triangulate() on the window's
///     observations and the window frames' poses (and each frame's own intrinsics, undistorted,
///     when it has them: maps read from COLMAP or Bundler; else options.triangulation's); landmarks
///     whose triangulation fails or whose max parallax is below min_parallax_deg are dropped (and
///     counted in `stats`).
/// Throws InvalidArgument ("split options: <why>") on invalid options, or if an in-window
/// observation names a frame missing from `map`, or a frame id is duplicated.
Map split_map(const Map& map, const SplitOptions& options, SplitStats* stats = nullptr);

}  // namespace lmalign
