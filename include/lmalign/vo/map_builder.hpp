// The RGB-D visual-odometry map builder (lmalign::vo; docs/map-builder.md; method.md §7).
//
// Front end: ORB features, tracking of every frame against the local map (the landmarks of the
// sliding window) by projection-guided descriptor matching and PnP RANSAC, keyframe selection,
// new landmarks back-projected from depth. Back end: a sliding-window bundle adjustment in Ceres
// over the last keyframes and their landmarks (reprojection and depth residuals, Huber loss);
// landmark covariances are the BA marginals (ceres::Covariance); landmarks never optimised get
// the covariance propagated from depth and pixel noise. Observations are (keyframe id, u, v) in
// raw pixels. The output Map is in the format of method.md §1.
//
// The library never prints; progress is reported through a callback. Results are deterministic:
// every RANSAC draw is seeded, Ceres runs single-threaded.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/vo/tum_sequence.hpp"

namespace lmalign::vo {

struct MapBuilderOptions {
  RgbdCamera camera;

  // --- front end
  int orb_features = 1000;           ///< ORB keypoints per image
  double orb_scale_factor = 1.2;     ///< ORB pyramid scale
  int orb_levels = 8;                ///< ORB pyramid levels
  int max_descriptor_distance = 64;  ///< Hamming distance limit of a match
  double match_ratio = 0.9;          ///< best / second-best distance ratio test
  double search_radius_px = 40.0;    ///< projection-guided search radius around the prediction
  double ransac_threshold_px = 3.0;
  int ransac_iterations = 200;
  int min_inliers = 20;      ///< fewer PnP inliers: the frame is not tracked
  double min_depth_m = 0.1;  ///< depth outside [min, max] is ignored
  double max_depth_m = 4.0;

  // --- keyframes: a new keyframe when the camera moved this far from the last keyframe, or when
  // fewer than keyframe_min_tracked_fraction of the last keyframe's tracked landmarks are tracked.
  double keyframe_translation_m = 0.05;
  double keyframe_rotation_deg = 5.0;
  double keyframe_min_tracked_fraction = 0.6;

  // --- back end
  int window_keyframes = 6;           ///< keyframes optimised by the sliding-window BA
  int ba_iterations = 8;              ///< Levenberg-Marquardt iterations per BA pass (two passes)
  double pixel_sigma_px = 1.0;        ///< keypoint noise at pyramid level 0 (x scale^level above)
  double depth_sigma_coeff = 0.0015;  ///< depth noise sigma = coeff * d^2 (m), at least 1 mm
  bool compute_covariances = true;

  /// The first keyframe takes the ground-truth pose (nearest within 0.02 s), so that the map is in
  /// the motion-capture frame. Needs groundtruth.txt. Otherwise it is the identity.
  bool init_from_ground_truth = false;
  /// Process at most this many frames (0: all).
  std::size_t max_frames = 0;
  /// Seed of the RANSAC draws (cv::theRNG is reset with it for every frame).
  unsigned long long seed = 1;

  bool is_valid(std::string* why = nullptr) const;
};

struct MapBuilderStats {
  std::size_t frames = 0;       ///< frames processed
  std::size_t frames_lost = 0;  ///< frames whose tracking failed (pose not estimated)
  std::size_t keyframes = 0;
  std::size_t landmarks = 0;
  std::size_t landmarks_two_plus = 0;       ///< landmarks with >= 2 observations
  double mean_observations = 0.0;           ///< per landmark
  std::size_t landmarks_ba_covariance = 0;  ///< covariance from BA marginals (others: propagated)
  std::size_t ba_runs = 0;
};

struct MapBuilderResult {
  Map map;                         ///< keyframes as FRAME (id = keyframe id), landmarks with n >= 1
  Trajectory keyframe_trajectory;  ///< stamped with the keyframes' RGB time stamps
  Trajectory frame_trajectory;     ///< every tracked frame (front-end pose)
  MapBuilderStats stats;
};

/// Called after each frame with (frames done, frames total).
using ProgressCallback = std::function<void(std::size_t, std::size_t)>;

/// Builds a map from a TUM RGB-D sequence. Throws IoError naming the file if an image is missing
/// or unreadable; ParseError naming the file if an RGB image is not 8-bit, or a depth image is not
/// 16-bit single-channel or not the size of the RGB image and the camera; InvalidArgument for bad
/// options, --init-from-groundtruth without ground truth at the first frame, or if tracking never
/// starts.
MapBuilderResult build_map(const TumSequence& sequence, const MapBuilderOptions& options,
                           const ProgressCallback& progress = {});

}  // namespace lmalign::vo
