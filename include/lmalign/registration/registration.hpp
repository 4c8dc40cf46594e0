// The registration driver: ICP with pluggable correspondence strategy (method.md §3), mirroring
// PCL's IterativeClosestPoint<PointXYZ, PointXYZ, double>::computeTransformation.
//
// Frames: the result is T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <cstddef>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/supported_range.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/convergence.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/search/kdtree.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {

/// The strategies selectable by name: first the paper's four (its table columns, run by
/// align()), then lmalign's own (issue 7; run by align_robust() with the preset options of
/// robust_strategy_options(), registration/robust.hpp). The type keeps its historical name;
/// `Strategy` is the same type.
enum class PaperStrategy {
  kBase,          ///< nearest neighbour, no weights
  kCovariance,    ///< weighted-kNN with w_cov (Eq. 1)
  kObservations,  ///< weighted-kNN with w_obs (Eq. 2)
  kMeanDistance,  ///< weighted-kNN with w_dist (Eqs. 3-4)
  // --- beyond the paper (docs/accuracy.md) ---
  kShrink,         ///< "shrink": nearest, max distance inf -> 1 -> 0.5 -> 0.25 -> 0.1 -> 0.05 m
  kShrinkCauchy,   ///< "shrink_cauchy": shrink + Cauchy IRLS
  kTrimmed,        ///< "trimmed": shrink + trimming to an estimated overlap (trimmed ICP)
  kMutual,         ///< "mutual": shrink + mutual nearest neighbours
  kRobustObs,      ///< "robust_obs": shrink_cauchy + w_obs in the estimation (the default
                   ///< before adaptive)
  kRobustObsKnn,   ///< "robust_obs_knn": robust_obs with the paper's weighted-kNN (w_obs) selection
  kRobustObs4Dof,  ///< "robust_obs_4dof": robust_obs estimating x, y, z, yaw only (z up)
  kGlobal,         ///< "global": global initialisation (any yaw, metres off; global_init.hpp), then
                   ///< robust_obs from its estimate; the initial guess is ignored
  kGlobalRobustObs,  ///< "global_robust_obs": robust_obs after a global yaw search (any start)
  kP2D,        ///< "p2d": shrink with the point-to-distribution cost (landmark covariances of both
               ///< maps; estimation_p2d.hpp)
  kRobustP2D,  ///< "robust_p2d": robust_obs with the point-to-distribution cost
  kAdaptive,   ///< "adaptive": the adaptive pipeline (registration/adaptive.hpp): data-derived
               ///< scales, global yaw-vote search, Mahalanobis gating, point-to-distribution;
               ///< the recommended default (issue 18)
};
using Strategy = PaperStrategy;
/// "base", "covariance", "observations", "distance", then "shrink", "shrink_cauchy", "trimmed",
/// "mutual", "robust_obs", "robust_obs_knn", "robust_obs_4dof", "global", "global_robust_obs",
/// "p2d", "robust_p2d", "adaptive".
std::string to_string(PaperStrategy strategy);
/// Inverse of to_string (also "none" for base, "mean_distance" for distance). Throws
/// InvalidArgument listing the names.
PaperStrategy parse_paper_strategy(const std::string& name);
/// The paper's four, in the paper's column order.
std::vector<PaperStrategy> all_paper_strategies();
/// lmalign's own strategies (issue 7), in declaration order.
std::vector<PaperStrategy> beyond_paper_strategies();
/// True for the paper's four (run by align()); false for lmalign's own (align_robust(), or
/// align_adaptive() for kAdaptive).
bool is_paper_strategy(PaperStrategy strategy);
/// The strategy `lmalign align` uses by default, chosen by measurement (docs/accuracy.md).
inline constexpr PaperStrategy kRecommendedStrategy = PaperStrategy::kAdaptive;

/// Every setting of one registration. Plain struct; check with is_valid().
struct RegistrationOptions {
  CorrespondenceKind correspondence = CorrespondenceKind::kNearest;
  /// Target weights for kWeightedKnn (ignored by kNearest).
  WeightKind weight = WeightKind::kUniform;
  /// Neighbourhood size k for kWeightedKnn; [1, 4096]. The paper's default is 5.
  int k = 5;
  /// Maximum correspondence distance, metres; infinite as in the paper.
  double max_correspondence_distance_m = std::numeric_limits<double>::infinity();
  /// Iteration budget and PCL's convergence epsilons (ICP defaults).
  ConvergenceOptions convergence;
  /// Record per-iteration history (number of correspondences, MSE).
  bool record_history = false;
  /// With record_history: also compute the fitness score at every iteration (one extra
  /// nearest-neighbour pass per iteration, as the paper's timing did).
  bool history_scores = false;
  /// Range for the final fitness score, metres (see fitness_score()); infinite by default.
  double score_max_range_m = std::numeric_limits<double>::infinity();
  /// Exact reuse of nearest-neighbour results between iterations (CorrespondenceWorkspace). It
  /// never changes a result: false searches the tree for every point, with bit-identical output.
  bool reuse_neighbours = true;

  /// The paper's setting for a strategy: base = nearest; the others weighted-kNN with its weight.
  /// Throws InvalidArgument for a strategy that is not one of the paper's four.
  static RegistrationOptions paper(PaperStrategy strategy, int k = 5);

  /// Ceres-style validation: false, and *why names the bad field and its value.
  bool is_valid(std::string* why = nullptr) const;
};

/// One ICP iteration, recorded when RegistrationOptions::record_history is set.
struct IterationRecord {
  int iteration = 0;  ///< 1-based
  std::size_t num_correspondences = 0;
  double mse_m2 = 0.0;  ///< mean squared correspondence distance (PCL's MSE), m^2
  /// Fitness score after this iteration's update (m^2); NaN unless history_scores was set.
  double score_m2 = std::numeric_limits<double>::quiet_NaN();
};

/// What a registration returns (after small_gicp's RegistrationResult and Ceres' Summary).
struct RegistrationResult {
  /// The estimate, p_target = T_target_source * p_source. Always finite.
  Isometry3 T_target_source = Isometry3::Identity();
  /// True when a convergence criterion (transform, absolute or relative MSE) stopped the run.
  /// Unlike PCL's hasConverged(), reaching max_iterations is reported as not converged.
  bool converged = false;
  TerminationReason termination = TerminationReason::kNotTerminated;
  int iterations = 0;
  /// Correspondences used in the last iteration.
  std::size_t num_correspondences = 0;
  /// Fitness score (method.md §4) of the initial guess and of the final estimate, m^2.
  double initial_score_m2 = std::numeric_limits<double>::infinity();
  double final_score_m2 = std::numeric_limits<double>::infinity();
  std::vector<IterationRecord> history;
  /// Wall time of the alignment (not of target preparation), seconds.
  double wall_time_s = 0.0;

  /// One line: termination, iterations, scores, time.
  std::string brief_report() const;
};

/// A target prepared once for many alignments: the kd-tree and each kind of confidence weight.
class PreparedTarget {
 public:
  /// From a map: builds the kd-tree over the landmark positions, computes all four weights and
  /// keeps the landmark covariances (for the point-to-distribution cost).
  /// Throws InvalidArgument if the map is invalid (see Map::validate()).
  explicit PreparedTarget(const Map& target, const WeightOptions& weight_options = {});
  /// From bare points: only uniform weights until set_weights() provides others, and no
  /// covariances until set_covariances() provides them.
  explicit PreparedTarget(Points3 points);

  /// Sets the weights used for `kind` (one per point, finite, >= 0). Throws InvalidArgument.
  void set_weights(WeightKind kind, std::vector<double> weights);
  /// Throws InvalidArgument if no weights of that kind are available.
  const std::vector<double>& weights(WeightKind kind) const;

  /// Sets the landmark position covariances (one 3x3 per point, m^2, target frame, finite).
  /// Throws InvalidArgument.
  void set_covariances(std::vector<Mat3> covariances_m2);
  bool has_covariances() const { return !covariances_.empty() || tree_.size() == 0; }
  /// One 3x3 position covariance per point (m^2, target frame). Throws InvalidArgument if the
  /// target has none (built from bare points without set_covariances()).
  const std::vector<Mat3>& covariances_m2() const;

  /// The target's up axis (unit, target frame): from the map's frames (estimate_up_axis(),
  /// registration/stages/data_scales.hpp) when built from a Map, else none until set_up_axis().
  const std::optional<Vec3>& up_axis() const { return up_axis_; }
  /// Sets it (normalised); nullopt clears it. Throws InvalidArgument for a zero or non-finite axis.
  void set_up_axis(std::optional<Vec3> up);

  const KdTree& tree() const { return tree_; }
  const Points3& points() const { return tree_.points(); }
  std::size_t size() const { return tree_.size(); }

 private:
  KdTree tree_;
  std::map<WeightKind, std::vector<double>> weights_;
  std::vector<Mat3> covariances_;
  std::optional<Vec3> up_axis_;
};

/// Aligns `source_points` (metres, source frame) to the prepared target, starting from
/// T_target_source_init. Mirrors PCL ICP's loop: transform the source by the current estimate,
/// find correspondences, estimate the increment by SVD, compose it, test convergence (see
/// ConvergenceCriteria). The source is re-transformed from the original points by the full
/// estimate each iteration (PCL transforms incrementally; see docs/conventions.md).
/// Deterministic for any thread count. Throws InvalidArgument on invalid options, a non-finite
/// initial guess, non-finite source points, an empty source or target, or a coordinate beyond
/// kMaxCoordinateM (core/supported_range.hpp; run_strategy() leaves such landmarks out instead).
/// Degenerate geometry (fewer than 3 correspondences, identical or collinear
/// points) gives a finite result with termination kNoCorrespondences or kDegenerate.
RegistrationResult align(const Points3& source_points, const PreparedTarget& target,
                         const RegistrationOptions& options,
                         const Isometry3& T_target_source_init = Isometry3::Identity());

struct PipelineSpec;
/// The engine's stages and settings that align() runs (pipeline.hpp): the paper's ICP as a preset.
PipelineSpec paper_pipeline_spec(const RegistrationOptions& options);

/// Convenience: aligns the landmark positions of two maps (builds a PreparedTarget).
RegistrationResult align_maps(const Map& source, const Map& target,
                              const RegistrationOptions& options,
                              const Isometry3& T_target_source_init = Isometry3::Identity());

}  // namespace lmalign
