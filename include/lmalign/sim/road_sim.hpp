// A seeded simulator of an outdoor stereo landmark map pair: a car driving down a road
// (KITTI-like; the outdoor counterpart of slam_sim.hpp's corridor).
//
// World frame = the road frame, axes as KITTI's camera frames: x right, y down, z forward along
// the road. The camera drives along +z in the right lane (x = 1.75 m, swaying by 0.3 m) at a
// height of camera_height_m above the ground (the ground is the plane y = +camera_height_m). The
// world, fixed by `seed` (both sessions see the same one):
//   - buildings in 12 m blocks on both sides, each block's facade set back facade_offset_m
//     +- 1.5 m from the road centre, up to facade_height_m above the ground: half of their
//     landmarks on the corners of windows on a regular 3 m x 3 m grid (70% of the cells have a
//     window; corners jittered by up to 10 cm, per corner), half anywhere on the wall (drawn per
//     session);
//   - a repetitive ground: lane-centre dashes (3 m long every 9 m), two continuous edge lines, and
//     a regular texture (a 1.5 m grid of points on the road, jittered by up to 15 cm per node).
// A session drives a stretch of road of length stretch_length_m, with a keyframe every
// frame_step_m, and maps the landmarks its keyframes see (so, as in real stereo VO, a map reaches
// max_range_m ahead of the road it was driven on: consecutive maps overlap in space even when
// their stretches do not).
// Each landmark has
//   - 2..max_observations observations from consecutive keyframes that see it at a range in
//     [min_range_m, max_range_m] inside the image (KITTI's 1242 x 375 px; the left camera's pixels,
//     with 0.5 px noise);
//   - a position triangulated from the stereo pair of its last (closest) observation: depth noise
//     from the disparity noise, sigma_z = z^2 sigma_d / (fx b), lateral noise z 0.5 px / fx, and
//     the matching covariance R diag(sl^2, sl^2, sz^2) R^T with R's third column along the viewing
//     ray (so the covariance's largest axis lies along the ray and grows with the range squared).
// The source session drives [0, L], the target session [(1 - overlap) L, (2 - overlap) L]:
// `overlap` is the fraction of the source's stretch that the target also drives (0 = consecutive
// windows).
// The target map is in the world frame; the source map in a frame moved by T_target_source^-1, so
// p_target = T_target_source * p_source (as simulate_map_pair()). Deterministic for a given seed
// (std::mt19937_64; the draws use explicit formulas, not <random> distributions).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "lmalign/core/types.hpp"
#include "lmalign/map/camera.hpp"
#include "lmalign/sim/slam_sim.hpp"

namespace lmalign::sim {

struct RoadSimOptions {
  /// Landmarks in each map (>= 10, <= 10,000,000).
  std::size_t num_landmarks = 3000;
  std::uint64_t seed = 1;
  /// Fraction of the source's stretch of road that the target also drives, in [0, 0.5].
  double overlap = 0.2;
  /// Length of road each session drives, metres (> 0).
  double stretch_length_m = 60.0;
  /// Stereo rig (KITTI's rectified rig, rounded): focal length (px) and baseline (m).
  double fx_px = 720.0;
  double baseline_m = 0.54;
  /// Disparity noise standard deviation, pixels (> 0).
  double disparity_sigma_px = 0.7;
  double camera_height_m = 1.6;
  /// Keyframe spacing along the road, metres (> 0).
  double frame_step_m = 1.0;
  /// A keyframe observes landmarks at ranges in [min_range_m, max_range_m] (0 < min < max).
  double min_range_m = 2.0;
  double max_range_m = 40.0;
  /// Observations per landmark: 2 .. max_observations (>= 2).
  int max_observations = 6;
  /// Facades at x = -/+ (facade_offset_m +- 1.5 m) (offset > 5 m), facade_height_m high (> 0).
  double facade_offset_m = 7.0;
  double facade_height_m = 10.0;
  /// Fraction of the landmarks on the ground, in [0, 1].
  double ground_fraction = 0.3;
  /// The true transform between the two maps' frames (see the file comment).
  Isometry3 T_target_source = Isometry3::Identity();

  /// The left camera (1242 x 375 px, principal point at the image centre).
  PinholeIntrinsics intrinsics() const { return {fx_px, fx_px, 621.0, 187.5}; }
  /// Ceres-style check: false and the bad field named in *why.
  bool is_valid(std::string* why = nullptr) const;
};

/// Simulates the pair (SlamMapPair: source, target, T_target_source). Throws InvalidArgument on
/// invalid options.
SlamMapPair simulate_road_pair(const RoadSimOptions& options);

}  // namespace lmalign::sim
