// Camera trajectories and their evaluation against ground truth, as the TUM RGB-D benchmark
// defines it (Sturm et al., IROS 2012; evaluate_ate.py and evaluate_rpe.py):
//   - TUM trajectory files: "timestamp tx ty tz qx qy qz qw" per line (quaternion scalar LAST),
//     pose camera-to-world (T_world_camera), '#' comments.
//   - association of two trajectories by nearest timestamp within a maximum difference;
//   - absolute trajectory error (ATE): RMSE of the position differences after the rigid
//     (rotation + translation, no scale) least-squares alignment of Horn / Umeyama;
//   - relative pose error (RPE) over a fixed time step.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign {

/// One pose of a trajectory: camera-to-world at a time stamp (seconds).
struct StampedPose {
  double timestamp_s = 0.0;
  Isometry3 T_world_camera = Isometry3::Identity();
};

/// A trajectory, sorted by time stamp after reading.
using Trajectory = std::vector<StampedPose>;

/// Reads a TUM trajectory file ("timestamp tx ty tz qx qy qz qw"; blank lines and '#' comments
/// ignored). Throws ParseError (file, line) on a wrong field count, a non-numeric or non-finite
/// value, a quaternion whose norm is off from 1 by more than 1e-3, or a duplicate time stamp;
/// IoError if the file cannot be opened. The result is sorted by time stamp.
Trajectory read_tum_trajectory(const std::string& path);

/// Writes a TUM trajectory file atomically (shortest round-trip doubles, quaternion x y z w).
void write_tum_trajectory(const std::string& path, const Trajectory& trajectory);

/// Reads a frame-times file: one "frame_id timestamp" per line (blank lines and '#' ignored).
/// Throws ParseError on malformed lines or duplicate frame ids.
std::vector<std::pair<Id, double>> read_frame_times(const std::string& path);

/// The frame poses of `map` as a trajectory, each stamped with its frame's time from
/// `frame_times`. Throws InvalidArgument naming the frame if a map frame has no time
/// (`frame_times_name` is used in the message). Frames are sorted by time stamp.
Trajectory trajectory_from_map(const Map& map,
                               const std::vector<std::pair<Id, double>>& frame_times,
                               const std::string& frame_times_name = "frame times");

/// A pair of associated poses: indices into the estimate and the ground truth.
struct PoseAssociation {
  std::size_t estimate_index = 0;
  std::size_t ground_truth_index = 0;
};

/// Associates each estimate pose with the ground-truth pose nearest in time, within
/// max_difference_s, as TUM's associate.py does: all candidate pairs are sorted by time difference
/// and taken greedily, so that each pose is used at most once. The result is sorted by estimate
/// time. `offset_s` is added to the ground-truth time stamps first.
std::vector<PoseAssociation> associate_trajectories(const Trajectory& estimate,
                                                    const Trajectory& ground_truth,
                                                    double max_difference_s = 0.02,
                                                    double offset_s = 0.0);

/// Summary statistics of a list of errors.
struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std_dev = 0.0;  ///< population standard deviation
  double min = 0.0;
  double max = 0.0;
};
ErrorStats error_stats(const std::vector<double>& errors);

/// Closed-form rigid alignment (Horn 1987 / Umeyama 1991 without scale, reflection guarded):
/// the T minimising sum |target_i - T * source_i|^2. Needs >= 3 non-collinear points for a unique
/// answer; throws InvalidArgument if the sizes differ or fewer than 1 point is given.
Isometry3 align_rigid(const Points3& source, const Points3& target);

struct AteResult {
  std::vector<PoseAssociation> pairs;
  /// T_gtworld_estworld: maps the estimate's world frame onto the ground truth's.
  Isometry3 T_gt_est = Isometry3::Identity();
  /// Per pair: |p_gt - T_gt_est * p_est|, metres (translational ATE).
  std::vector<double> translation_errors_m;
  /// Per pair: rotation angle of R_gt^T (R_gt_est R_est), degrees (after the same alignment).
  std::vector<double> rotation_errors_deg;
  ErrorStats translation_m;
  ErrorStats rotation_deg;
};

struct AteOptions {
  double max_difference_s = 0.02;
  double offset_s = 0.0;
  /// Align the estimate to the ground truth (the TUM definition). false: compare as given.
  bool align = true;
};

/// Absolute trajectory error. Throws InvalidArgument if fewer than 3 poses associate (the message
/// gives both time ranges).
AteResult absolute_trajectory_error(const Trajectory& estimate, const Trajectory& ground_truth,
                                    const AteOptions& options = {});

struct RpeOptions {
  double max_difference_s = 0.02;
  double offset_s = 0.0;
  /// Time step between the two poses of each pair, seconds (TUM's default: 1 s, drift per second).
  double delta_s = 1.0;
  /// A pair (i, j) is used if |t_j - t_i - delta_s| <= delta_tolerance_s, j the associated pose
  /// nearest to t_i + delta_s.
  double delta_tolerance_s = 0.1;
};

struct RpeResult {
  /// Per pair: |translation of E|, metres, with E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j).
  std::vector<double> translation_errors_m;
  /// Per pair: rotation angle of E, degrees.
  std::vector<double> rotation_errors_deg;
  ErrorStats translation_m;
  ErrorStats rotation_deg;
};

/// Relative pose error over the associated poses (TUM's evaluate_rpe.py with --fixed_delta and
/// delta_unit 's'). Returns an empty result (count 0) if no pair spans delta_s.
RpeResult relative_pose_error(const Trajectory& estimate, const Trajectory& ground_truth,
                              const RpeOptions& options = {});

}  // namespace lmalign
