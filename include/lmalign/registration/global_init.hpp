// Global initialisation: an alignment that does not need an initial guess.
//
// For gravity-aligned maps (visual-inertial SLAM, indoor robots), the unknown rotation is mostly
// a yaw about the up axis. global_align() searches it exhaustively:
//   1. Yaw hypotheses every yaw_step_deg over [-180, 180).
//   2. For each yaw, the translation by voting (a Hough transform over translations): every
//      sampled source landmark, rotated, votes for p_target - R p_source with every sampled
//      target landmark, in a grid of vote_cell_m cells. Landmarks that exist in both maps vote
//      for the same cell; the rest spread out. Partial overlap only lowers the peak.
//   3. The best yaws (local maxima of the peak votes, by yaw) are refined by ICP (nearest
//      neighbour, full 6 DoF) with a shrinking maximum correspondence distance.
//   4. The refined hypothesis with the largest inlier fraction wins (source landmarks within
//      inlier_distance_m of a target landmark; ties: the smaller inlier RMS).
// No ground truth is used anywhere. Deterministic: fixed samples (strided), no random draws, and
// every parallel loop writes its own slots.
//
// Frames: T_target_source, p_target = T_target_source * p_source. Units: metres, degrees.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/registration.hpp"

namespace lmalign {

/// Settings of global_align(). Plain struct; check with is_valid().
struct GlobalInitOptions {
  /// The up (gravity) axis, the same in both maps; any non-zero vector (normalised). z default.
  Vec3 up = Vec3::UnitZ();
  /// Spacing of the yaw hypotheses, degrees; (0, 90].
  double yaw_step_deg = 10.0;
  /// Edge of a translation vote cell, metres; > 0. A vote grid larger than max_vote_cells grows
  /// its cells until it fits (large maps).
  double vote_cell_m = 0.10;
  std::size_t max_vote_cells = std::size_t{1} << 23;
  /// Source and target landmarks that vote (strided samples of each map); >= 3.
  std::size_t vote_source_samples = 128;
  std::size_t vote_target_samples = 1024;
  /// How many yaw hypotheses are refined by ICP; >= 1.
  std::size_t hypotheses = 4;
  /// The refinement: ICP stages with these maximum correspondence distances (metres, each > 0,
  /// at least one), each of at most refine_iterations iterations (>= 1).
  std::vector<double> refine_schedule_m = {0.5, 0.2, 0.08, 0.04};
  int refine_iterations = 30;
  /// A source landmark within this distance (metres, > 0) of a target landmark is an inlier.
  double inlier_distance_m = 0.05;

  /// Ceres-style validation: false, and *why names the bad field and its value.
  bool is_valid(std::string* why = nullptr) const;
};

/// One yaw hypothesis: its coarse pose from the vote, and, if refined, the refined pose.
struct GlobalHypothesis {
  double yaw_deg = 0.0;
  std::size_t votes = 0;  ///< peak votes (3x3x3 cells) of its translation
  Isometry3 T_coarse = Isometry3::Identity();
  bool refined = false;
  Isometry3 T_refined = Isometry3::Identity();
  double inlier_fraction = 0.0;  ///< of all source landmarks, at inlier_distance_m
  double inlier_rms_m = 0.0;     ///< RMS distance of the inliers to their nearest target
};

struct GlobalInitResult {
  /// The chosen estimate, p_target = T_target_source * p_source. Always finite.
  Isometry3 T_target_source = Isometry3::Identity();
  double inlier_fraction = 0.0;
  double inlier_rms_m = 0.0;
  /// Every yaw hypothesis, by decreasing votes; the refined ones carry their refinement.
  std::vector<GlobalHypothesis> hypotheses;
  double wall_time_s = 0.0;
};

/// Aligns `source_points` (metres) to the prepared target without an initial guess (see the
/// file comment). Throws InvalidArgument on invalid options, or if the source has fewer than 3
/// points or a non-finite point.
GlobalInitResult global_align(const Points3& source_points, const PreparedTarget& target,
                              const GlobalInitOptions& options = {});

}  // namespace lmalign
