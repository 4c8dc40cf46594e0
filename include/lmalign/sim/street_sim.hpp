// A seeded simulator of aperiodic streets seen by a KITTI-like stereo camera on a car: windows of
// one forward drive, each mapped as a stereo visual odometry would map it. The outdoor
// counterpart of road_sim.hpp without its periodicity (road_sim.hpp stays the aliasing case).
//
// World frame: axes as KITTI's camera frames, x right, y down, z forward at the start of the
// drive; the ground is the plane y = +camera_height_m; the drive starts at the origin heading +z.
// Everything below is fixed by `seed` (every window sees the same world):
//   - the road's centre line: segments of explicit random kinds, 45% straight (20-80 m), 35%
//     curves (radius 60-250 m, 10-45 deg), 20% turns (radius 10-16 m, 90 deg, followed by at
//     least 30 m of straight road); the heading stays within [-45, 90] deg of +z, or within its
//     mirror image (per world; a turn or curve that would leave it goes the other way, or is a
//     straight if neither way stays), so the road never comes back across its own view;
//   - per side, a sequence of lots: 80% buildings (width 6-30 m, facade 9-18 m from the centre
//     line, 6-22 m high, each with its own window grid: column spacing 2.2-4 m, storey height
//     2.8-3.6 m, window size, fill ratio 50-95%; window corners, facade texture at 3-10 per
//     m^2, the facade's vertical edges and roof line, and side walls where neighbouring setbacks
//     differ), 20% gaps (4-20 m: side streets, empty lots);
//   - trees (in 50 m blocks that have them with probability 0.5, about every 12 m; a trunk and a
//     crown of 100-250 points 1.5-3 m in radius), poles every 25-45 m (6-9 m high, with a lamp
//     arm), parked cars (in 40 m blocks that have them with probability 0.6; boxes 3.8-5 m long
//     with 80-160 points, gaps 0.5-8 m) and the ground (lane-centre dashes whose phase changes per
//     road segment, edge lines, kerbs and random road texture at 0.5-3 per m^2, drawn per 10 m);
//   - on the inside of a curve, nothing closer to the curve's centre than 0.6 of its radius (so a
//     turn is a crossing, with no building in it); facades and side walls are seen only from the
//     side they face.
// The drive: keyframes every frame_step_m +- 10% (explicit uniform jitter) along the centre line
// in the right lane (1.75 m right of the centre, swaying by 0.2 m), the camera camera_height_m
// above the ground with pitch and roll oscillating by 0.4 and 0.3 deg. Window k holds keyframes
// [k (F - round(overlap F)), ... + F) of the drive, F = window_frames: consecutive windows share
// round(overlap F) keyframes (the same poses, as windows cut from one odometry).
// Each window maps num_landmarks of the world's features that at least two of its consecutive
// keyframes see with both cameras (KITTI's 1242 x 375 px, fx = fy = fx_px, the principal point at
// the image centre) at a depth in [min_range_m, max_range_m]. A feature seen from the depth z of
// its last observation is kept with weight min(1, (10 m / z)^2) (Efraimidis-Spirakis weighted
// sampling without replacement: a detector keeps a few features per image area, and a far
// surface packs many features into little area; at 3,000 landmarks per 30 keyframes the median
// depth is 22-29 m, KITTI's maps 16-23 m). Each landmark has
//   - 2..max_observations observations from consecutive keyframes: left-image pixels (u, v) and
//     right-image column u_R, each with Gaussian noise pixel_sigma_px (the track ends before an
//     observation whose noisy disparity is below 1 px, and a landmark needs two);
//   - a position and covariance as kitti_stereo_vo/SOURCE.md makes them: per observation, the
//     stereo back-projection of (u, u_R, v) and its covariance pixel_sigma_px^2 J J^T (J the
//     back-projection's Jacobian) rotated to the world, fused by summing information
//     (information-weighted mean, no refinement). The covariance's long axis lies along the
//     viewing ray and grows with the depth squared.
// simulate_street_pair(): window 0 is the source, window 1 the target. The target map is in the
// world frame; the source map in a frame moved by T_target_source^-1, so p_target =
// T_target_source * p_source (as road_sim.hpp). simulate_street_windows(): each map in the frame
// of its own first keyframe (as a visual odometry starts its world), with T_world_map.
// Deterministic for a given seed: std::mt19937_64 through explicit formulas (uniform01,
// Box-Muller), not <random> distributions, so the maps are the same with any standard library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/camera.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/sim/slam_sim.hpp"

namespace lmalign::sim {

struct StreetSimOptions {
  /// Landmarks in each map (>= 10, <= 1,000,000); the simulator throws InvalidArgument if the
  /// window sees fewer features.
  std::size_t num_landmarks = 3000;
  std::uint64_t seed = 1;
  /// Fraction of a window's keyframes that the next window shares, in [0, 0.75].
  double overlap = 0.25;
  /// Keyframes per window, in [2, 100000].
  std::size_t window_frames = 30;
  /// Mean keyframe spacing along the road, metres, in (0, 10].
  double frame_step_m = 1.0;
  /// Stereo rig (KITTI's rectified rig, rounded): focal length (px) and baseline (m), > 0.
  double fx_px = 718.0;
  double baseline_m = 0.54;
  /// Pixel noise of u, v and u_R, pixels (> 0); also the sigma of the covariances.
  double pixel_sigma_px = 1.0;
  double camera_height_m = 1.65;
  /// A keyframe observes features at depths in [min_range_m, max_range_m] (0 < min < max <= 1000).
  double min_range_m = 2.0;
  double max_range_m = 150.0;
  /// Observations per landmark: 2 .. max_observations (>= 2).
  int max_observations = 5;
  /// The true transform between the pair's frames (simulate_street_pair only).
  Isometry3 T_target_source = Isometry3::Identity();

  /// The left camera (1242 x 375 px, principal point at the image centre).
  PinholeIntrinsics intrinsics() const { return {fx_px, fx_px, 621.0, 187.5}; }
  /// Ceres-style check: false and the bad field named in *why.
  bool is_valid(std::string* why = nullptr) const;
};

/// Windows 0 (source) and 1 (target) of the drive (SlamMapPair: source, target,
/// T_target_source). Throws InvalidArgument on invalid options or too few visible features.
SlamMapPair simulate_street_pair(const StreetSimOptions& options);

struct StreetWindows {
  /// Window k, in the frame of its first keyframe (that keyframe's pose is the identity).
  std::vector<Map> maps;
  /// p_world = T_world_map[k] * p_map: the pose of window k's first keyframe in the world frame.
  std::vector<Isometry3> T_world_map;
  /// The true position of each landmark of maps[k] (same order), in that map's frame, metres.
  std::vector<Points3> true_positions;
};

/// num_windows (>= 2, <= 10,000) consecutive windows of one drive, each mapped on its own (its
/// own noise and landmark selection; T_target_source is not used). Throws InvalidArgument.
StreetWindows simulate_street_windows(const StreetSimOptions& options, std::size_t num_windows);

/// The road's centre line of the world of `seed` in the world frame (on the camera's height,
/// y = 0): points every step_m (> 0) of arc length from 0 to length_m (> 0, <= 1e6). For
/// statistics along the road (arc length of a landmark = that of its nearest point). Throws
/// InvalidArgument.
std::vector<Vec3> street_centre_line(std::uint64_t seed, double length_m, double step_m = 0.5);

}  // namespace lmalign::sim
