// The adaptive pipeline: lmalign's recommended default (docs/accuracy.md, "The
// adaptive default"). It is written as explicit stages, each in its own file under stages/:
//   scales          DataScales of both maps: landmark spacing, covariance floor, size, up axis
//                   (stages/data_scales.hpp). Every metric setting below is derived from them.
//   initialisation  global: yaw-vote hypotheses over every yaw (stages/yaw_vote_search.hpp),
//                   plus the initial guess if one is given; prior-bounded: the same search
//                   confined to 3 sigma of the guess, from the guess's rotation and, when the
//                   maps' up axes disagree with it by more than half a yaw step and at most
//                   3 sigma, also from the guess tilted to agree with them; given: the guess
//                   alone.
//   selection       the k Euclidean nearest target landmarks of each source landmark, keeping
//   + gating        the one with the smallest Mahalanobis distance under both landmarks'
//                   covariances, the floor and the current pose uncertainty, if it passes a
//                   chi-square test (stages/mahalanobis_gate.hpp). The pose uncertainty starts
//                   at a fraction of the hypothesis' resolution (or of the prior) and halves each
//                   time the estimate settles, down to zero: the gate never is unbounded.
//   weighting       Cauchy kernel of the Mahalanobis distance times the pair's information.
//   estimation      one point-to-distribution Gauss-Newton step per iteration (6 or 4 DoF;
//                   stages/p2d_step.hpp).
//   convergence     settled when a step is below 1e-3 of the covariance floor (and that over
//                   the map's radius in rotation) at zero pose uncertainty; an iteration budget.
//   scoring         each refined hypothesis is scored by its covariance-gated inliers
//                   (gated_inlier_score); the best wins and is refined on every landmark.
//   trust           enough gated inliers, most of the landmarks near a target landmark within
//                   their covariances (inlier ratio), no distinct pose scoring nearly as well
//                   (ambiguity), and a non-degenerate covariance.
//
// Frames: T_target_source, p_target = T_target_source * p_source. Deterministic for any thread
// count.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/stages/complete_search.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

/// Settings of the adaptive pipeline. Every length is derived from the data (DataScales); what
/// is left are dimensionless ratios, counts and probabilities. Plain struct; is_valid().
struct AdaptiveOptions {
  // --- initialisation ---
  /// Without a prior: the complete search (stages/complete_search.hpp; true) or the yaw vote
  /// alone (false). search.yaw_step_deg and search.hypotheses apply to both.
  bool complete_search = true;
  CompleteSearchOptions complete;
  YawVoteOptions search;
  /// The vote cell is max(spacing, 2 sin(step / 2) * source radius): what half a yaw step moves
  /// a landmark twice the typical distance from the centre. Multiplied by this factor, > 0.
  double vote_cell_factor = 1.5;
  /// The pose uncertainty of the gate at the start of a hypothesis' refinement, as a fraction of
  /// its resolution (two vote cells, one yaw step) or of the prior's sigmas; (0, 10].
  double start_sigma_factor = 0.3;
  /// Source landmarks (evenly strided) used to refine and score the hypotheses; the winner is
  /// refined on all of them. >= 16.
  std::size_t hypothesis_samples = 1024;
  /// Up axis used for a map whose frames do not give one (unit after normalisation).
  Vec3 default_up = Vec3::UnitZ();
  /// Without a prior, a map's landmark plane normal (landmark_plane_normal()) becomes a second
  /// up-axis candidate when it is more than this many degrees from the frames' up axis, and the
  /// search votes for every pair of the two maps' candidates; [0, 180] (180 = never). The frames
  /// fail on short windows of a hand-held camera, the plane on maps without a dominant
  /// horizontal surface: the search keeps the best hypotheses of both.
  double second_up_min_angle_deg = 10.0;

  // --- selection and gating ---
  MahalanobisGateOptions gate;
  /// Covariance floor, metres; 0 = the data's (the larger of the two maps' DataScales::floor_m).
  double floor_m = 0.0;

  // --- estimation ---
  /// Estimate x, y, z and the yaw about the target's up axis only (4 DoF).
  bool four_dof = false;

  // --- convergence ---
  int max_iterations = 120;           ///< per refinement, >= 1
  int max_iterations_per_level = 15;  ///< before the pose uncertainty shrinks anyway, >= 1
  /// Each time the estimate settles, the gate's pose uncertainty is multiplied by this; (0, 1).
  /// Below the floor it becomes zero.
  double sigma_decay = 0.5;
  /// Settled: a step's translation below settle_ratio * floor and its rotation below
  /// settle_ratio * floor / source radius (radians); (0, 1].
  double settle_ratio = 1e-3;
  /// At a level whose pose uncertainty is still above zero, a step below this fraction of it
  /// (translation and rotation) also counts as settled; [0, 1).
  double level_settle_ratio = 0.0;

  // --- trust ---
  /// Untrusted when a distinct pose scores at least this fraction of the best; (0, 1].
  double max_ambiguity = 0.85;
  /// Two refined hypotheses are distinct poses when they move a landmark at the source's
  /// median distance from its centre apart by more than this many vote cells (the search's
  /// resolution); > 0.
  double distinct_cells = 4.0;
  /// Untrusted below this many gated inliers, >= 3.
  std::size_t min_inliers = 12;
  /// Untrusted when fewer than this fraction of the source landmarks that pass the gate widened
  /// by one vote cell of pose uncertainty (those near a target landmark) pass it at the estimate
  /// itself: a right pose puts the overlapping landmarks within their covariances, a wrong one
  /// only near some landmark. [0, 1]. The ratios seen at right and wrong poses:
  /// docs/accuracy.md.
  double min_inlier_ratio = 0.2;
  /// Untrusted when the inliers' residuals need the landmark covariances scaled by more than
  /// this (the covariance scale k^2, estimated robustly from the median Mahalanobis d^2 of the
  /// gated inliers against a chi-square of 3 dof truncated at the gate): the maps disagree beyond
  /// their uncertainty. Real maps state covariances 30-40% too small (k^2 about 2), which must
  /// pass. >= 1.
  double max_covariance_scale = 3.0;
  /// Untrusted when a distinct refined pose scores alias_ambiguity of the best while the inliers'
  /// mean NIS exceeds alias_nis_ratio of its expectation (2.89 at the default gate): repeated
  /// structure gives an aliased pose both rivals and residuals its covariances do not explain.
  /// alias_ambiguity in (0, 1], alias_nis_ratio >= 1.
  double alias_ambiguity = 0.7;
  double alias_nis_ratio = 1.2;

  // --- uncertainty ---
  /// Edge of the spatial blocks of the cluster-robust covariance (p2d_cluster_covariance), as a
  /// fraction of the source's radius (DataScales::radius_m); > 0. Landmarks in one block may
  /// share an error; blocks are treated as independent. 0.5 gives 30-120 blocks on the real
  /// pairs; from 0.05 to 0.8 the mean NEES changes by less than 3x (docs/accuracy.md).
  double covariance_block_factor = 0.5;
  /// Half-sample covariance (balanced repeated replication over spatial halves; docs/accuracy.md,
  /// "Uncertainty of the adaptive default"): the overlap landmarks (those that pass the gate
  /// widened by one vote cell at the estimate) are cut in two by this many vertical planes
  /// through their centroid (at k x 180 deg / n about the source's up axis from their widest
  /// horizontal direction) and by one horizontal plane; each half is re-aligned from the
  /// estimate (the final refinement on that half only, the gate at its floor: no pose
  /// uncertainty); the covariance is raised (covariance_max) to the mean of
  /// (xi_half - xi)(xi_half - xi)^T over the halves (pose_error_twist against the estimate).
  /// It sees what the residuals cannot: whole regions of a map displaced together (frames' pose
  /// errors, depth distortion, drift), which the rigid fit absorbs in part. A half re-aligned from
  /// fewer than min_inliers landmarks, or whose refinement fails, is left out; with fewer than
  /// half of the halves the block covariance stays. 0: off. >= 0; costs 2 (n + 1) refinements of
  /// half the overlap. Its cost and its effect on the NEES: docs/accuracy.md.
  int covariance_half_sample_planes = 8;

  bool is_valid(std::string* why = nullptr) const;
};

/// One hypothesis after its refinement.
struct AdaptiveHypothesis {
  Isometry3 T_start = Isometry3::Identity();
  Isometry3 T_refined = Isometry3::Identity();
  std::size_t votes = 0;  ///< 0 for the initial guess
  double score = 0.0;     ///< gated_inlier_score on the hypothesis samples
  bool from_guess = false;
};

/// The result: a RegistrationResult (termination kTransform when the final refinement settled,
/// kMaxIterations, kNoCorrespondences or kDegenerate) plus what the pipeline knows.
struct AdaptiveResult {
  RegistrationResult registration;
  /// "global", "prior" or "given".
  std::string initialisation;
  /// Gated inlier score and inliers of the estimate on every source landmark.
  double score = 0.0;
  std::size_t num_inliers = 0;
  /// Mean Mahalanobis d^2 of those inliers (dimensionless), and its expectation when the
  /// covariances hold (alias_nis_ratio), and the covariance scale (max_covariance_scale).
  double mean_nis = 0.0;
  double expected_nis = 0.0;
  /// How much the landmark covariances must be scaled for the inliers' residuals (k^2, robust:
  /// from the median d^2; dimensionless, 1 when they hold); the reported covariance is
  /// multiplied by it when it is above 1.
  double covariance_scale = 1.0;
  /// Source landmarks that pass the gate widened by one vote cell of pose uncertainty (those in
  /// the overlap, roughly), and num_inliers over it.
  std::size_t num_overlap = 0;
  double inlier_ratio = 0.0;
  /// Best score of a distinct hypothesis over the best's, on the hypothesis samples (0 if none).
  double ambiguity = 0.0;
  /// The best distinct refined pose (the rival that `ambiguity` measures; empty without one),
  /// T_target_source as the estimate's, and how far it is from the estimate: the displacement
  /// of the source's centre (m, target frame) and the rotation between them (deg).
  std::optional<Isometry3> rival_T_target_source;
  double rival_distance_m = 0.0;
  double rival_angle_deg = 0.0;
  /// Covariance of the estimate, lmalign's convention (uncertainty.hpp): 6 DoF, the
  /// cluster-robust p2d_cluster_covariance of the final pairs raised to the half-sample
  /// covariance (covariance_half_sample_planes); 4 DoF, p2d_covariance. `valid` as
  /// p2d_covariance of the final step says (singular normal equations: not valid).
  PoseCovariance covariance;
  /// Halves that entered the half-sample covariance (0: it did not apply).
  std::size_t num_half_samples = 0;
  bool trustworthy = false;
  std::string trust_reason;  ///< why not, or "ok"
  DataScales source_scales;
  DataScales target_scales;
  double floor_m = 0.0;
  double vote_cell_m = 0.0;
  /// The maps' up axes (their frames', or default_up), and the up-axis candidates the search
  /// voted with (these first, then a landmark plane normal that disagrees; empty when no search
  /// ran).
  Vec3 up_source = Vec3::UnitZ();
  Vec3 up_target = Vec3::UnitZ();
  std::vector<Vec3> ups_source;
  std::vector<Vec3> ups_target;
  std::vector<AdaptiveHypothesis> hypotheses;  ///< by decreasing score
};

/// Aligns `source` to `target` (see the file comment). Initialisation: with `prior`, the search
/// confined to it around `initial_guess` (identity if null); without, the global search, with
/// the initial guess added as one more hypothesis when given. The target's up axis comes from
/// PreparedTarget::up_axis(), else options.default_up.
/// Throws InvalidArgument on invalid options or prior, a non-finite or non-rigid initial guess,
/// an empty source or target, a non-finite landmark, or covariance counts that do not match.
/// Fewer than 3 landmarks on a side give termination kNoCorrespondences, untrusted.
AdaptiveResult align_adaptive(const SourceLandmarks& source, const PreparedTarget& target,
                              const AdaptiveOptions& options = {},
                              const Isometry3* initial_guess = nullptr,
                              const PriorSigma* prior = nullptr);

/// The engine's stages and settings that align_adaptive() runs (pipeline.hpp).
PipelineSpec adaptive_pipeline_spec(const AdaptiveOptions& options);

}  // namespace lmalign
