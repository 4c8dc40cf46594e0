// Beyond the paper (issue 7): an accurate ICP for partial-overlap landmark maps. Correspondence
// rejection (a maximum distance on a shrinking schedule, trimming to an overlap ratio given or
// estimated, mutual nearest neighbours), each combinable with the paper's weighted-kNN
// selection; weighted Umeyama with IRLS robust kernels times landmark confidences; optional
// 4-DoF (x, y, z, yaw) estimation; an optional point-to-distribution cost with both maps'
// landmark covariances (estimation_p2d.hpp); an optional global yaw search for far starts. The
// paper's align() is untouched.
//
// Frames: the result is T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/registration/estimation_4dof.hpp"
#include "lmalign/registration/estimation_p2d.hpp"
#include "lmalign/registration/global_init.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {

/// IRLS robust kernels (Zhang 1997; Black & Rangarajan 1996). The weight of a residual r (m)
/// at scale c (m) is rho'(r) / r:
/// - kNone: 1
/// - kHuber: 1 if |r| <= c, else c / |r|
/// - kCauchy: 1 / (1 + (r/c)^2)
/// - kGemanMcClure: 1 / (1 + (r/c)^2)^2
enum class RobustKernel { kNone, kHuber, kCauchy, kGemanMcClure };
std::string to_string(RobustKernel kernel);  ///< "none", "huber", "cauchy", "geman_mcclure"
/// Inverse of to_string. Throws InvalidArgument listing the names.
RobustKernel parse_robust_kernel(const std::string& name);
/// The IRLS weight of residual `residual_m` at scale `scale_m` (> 0; +inf gives 1). In [0, 1].
double robust_weight(RobustKernel kernel, double residual_m, double scale_m);
/// The Cauchy weight 1 / (1 + u2) of a squared normalised residual u2 = (r / c)^2 (>= 0): the one
/// Cauchy kernel of lmalign (robust_weight's, and the Mahalanobis kernel's with u2 = d^2 / c).
inline double cauchy_weight(double u2) { return 1.0 / (1.0 + u2); }

/// Which degrees of freedom are estimated.
enum class DegreesOfFreedom {
  k6,  ///< full SE(3): weighted Umeyama (estimate_rigid_transform)
  k4,  ///< x, y, z and yaw about the up axis (estimate_4dof_transform); roll, pitch kept
};

/// Trimmed ICP's overlap estimate (Chetverikov et al. 2005, "Robust Euclidean alignment of 3D
/// point sets: the trimmed ICP"): given the squared residuals, the fraction xi in
/// [min_ratio, 1] (steps of 0.01) minimising e(xi) / xi^(1 + lambda), with e(xi) the mean of
/// the ceil(xi n) smallest squared residuals. Returns 1 for fewer than 2 residuals.
/// Throws InvalidArgument unless 0 < min_ratio <= 1 and lambda >= 0.
double estimate_overlap_ratio(std::vector<double> residuals_sq_m2, double min_ratio = 0.4,
                              double lambda = 2.0);

/// Keeps the ceil(ratio * n) correspondences of smallest distance_sq_m2 (ties: lower source
/// index first), in increasing source index. ratio in (0, 1]; throws InvalidArgument otherwise.
void trim_correspondences(Correspondences& correspondences, double ratio);

/// Keeps only mutual nearest neighbours: pairs (s, t) such that s is also the nearest of the
/// `moved_source` points to target point t (kd-tree total order: distance, then lower index).
/// `moved_source` are the source points already in the target frame (metres).
void keep_mutual(const Points3& moved_source, const Points3& target_points,
                 Correspondences& correspondences);

/// The cost the estimation step minimises on fixed correspondences.
enum class EstimationCost {
  /// sum w |q - T p|^2: weighted Umeyama (6-DoF) or the 4-DoF closed form. The default.
  kPointToPoint,
  /// sum w r^T (C_t + R C_s R^T + floor^2 I)^-1 r with the landmark covariances of both maps
  /// (estimate_point_to_distribution, estimation_p2d.hpp; GICP-like). 6-DoF only.
  kPointToDistribution,
};
std::string to_string(EstimationCost cost);  ///< "point_to_point", "point_to_distribution"
/// Inverse of to_string (also "p2p", "p2d"). Throws InvalidArgument listing the names.
EstimationCost parse_estimation_cost(const std::string& name);

/// What the IRLS kernel is evaluated on with the point-to-distribution cost.
enum class KernelResidual {
  /// The Euclidean residual |r| in metres, as with point-to-point (the default: measured better
  /// on the real pair, docs/accuracy.md).
  kEuclidean,
  /// The Mahalanobis residual sqrt(r^T Omega r), converted so that kernel_scale_sigma of it
  /// count as kernel_scale_m: the kernel sees sqrt(r^T Omega r) * kernel_scale_m /
  /// kernel_scale_sigma (so the schedule of kernel scales is kept).
  kMahalanobis,
};
std::string to_string(KernelResidual residual);  ///< "euclidean", "mahalanobis"

struct RobustRegistrationOptions {
  // --- selection (method.md §3) ---
  /// kNearest, or the paper's weighted-kNN with `selection_weight` and `k`.
  CorrespondenceKind selection = CorrespondenceKind::kNearest;
  WeightKind selection_weight = WeightKind::kUniform;
  int k = 5;  ///< [1, 4096]

  // --- rejection ---
  /// Maximum correspondence distance per level, metres, non-increasing, each > 0 (+inf allowed
  /// first). One value = a fixed maximum distance. The run moves to the next level when the
  /// estimate settles (see settle_*) or after max_iterations_per_level; it ends when it settles
  /// at the last level. Default: unlimited (the paper's basin), then shrinking to 5 cm.
  std::vector<double> max_distance_schedule_m{
      std::numeric_limits<double>::infinity(), 1.0, 0.5, 0.25, 0.1, 0.05};
  /// Trimming and mutual filtering act only at levels with a finite maximum distance (at an
  /// unlimited level they shrink the basin). Keep this fraction of the correspondences that
  /// pass the distance gate, (0, 1] (1 = all).
  double trim_ratio = 1.0;
  /// Estimate the trim ratio each iteration (estimate_overlap_ratio); overrides trim_ratio.
  bool estimate_overlap = false;
  double min_overlap_ratio = 0.4;  ///< lower bound of the estimate, (0, 1]
  /// Keep only mutual nearest neighbours (keep_mutual).
  bool mutual = false;

  // --- estimation ---
  RobustKernel kernel = RobustKernel::kNone;
  /// Kernel scale c at a level of maximum distance d: max(kernel_scale_m, kernel_scale_ratio * d)
  /// (so an unlimited level is unweighted). kernel_scale_m > 0, kernel_scale_ratio >= 0.
  double kernel_scale_m = 0.02;
  double kernel_scale_ratio = 0.5;
  /// IRLS re-weightings per ICP iteration on fixed correspondences, >= 1.
  int irls_iterations = 3;
  /// Landmark confidence of the matched target landmark, multiplied into the estimation weight
  /// (kUniform = none).
  WeightKind estimation_weight = WeightKind::kUniform;
  DegreesOfFreedom dof = DegreesOfFreedom::k6;
  UpAxis up_axis = UpAxis::kZ;
  /// Point-to-point (default) or point-to-distribution. kPointToDistribution needs the landmark
  /// covariances of both maps (the target's from its Map, the source's passed to align_robust)
  /// and dof = k6 (is_valid refuses k4). Each IRLS re-weighting then runs p2d.max_iterations
  /// Gauss-Newton steps (default 1: the ICP loop iterates anyway), warm-started from the last.
  EstimationCost cost = EstimationCost::kPointToPoint;
  /// Gauss-Newton steps per IRLS step (1), covariance floor (5 mm).
  PointToDistributionOptions p2d = {/*max_iterations=*/1};
  /// The point-to-distribution cost acts at levels whose maximum distance is <= this (metres,
  /// > 0; +inf = every level, the unlimited one included); coarser levels estimate
  /// point-to-point. While many pairs are wrong, the covariances' long axes let them slide: on
  /// the real pair robust_p2d with P2D at every level lost robust_obs's basin at yaw 50 deg and
  /// at -X+Y 0.5 m yaw 30 deg; from the 1 m level on, the latter; from 0.25 m on, yaw 30 deg;
  /// from 0.1 m on (the default) it kept all 45 protocol starts (docs/accuracy.md).
  double p2d_max_level_distance_m = 0.1;
  KernelResidual kernel_residual = KernelResidual::kEuclidean;  ///< P2D only
  double kernel_scale_sigma = 3.0;  ///< kMahalanobis only: finite > 0 (see KernelResidual)

  // --- initialisation ---
  /// Start from global_align() (any yaw, translation by voting; global_init.hpp) instead of
  /// the initial guess, which is then ignored. The robust loop refines its estimate.
  bool global_initialisation = false;
  GlobalInitOptions global;
  // --- global initialisation (issue 7; no ground truth used) ---
  /// Before the local loop, try yaw_hypotheses yaws about the up axis (evenly spaced from 0),
  /// each rotating the source about its centroid and moving the centroid onto the target's
  /// centroid, plus the initial guess itself. Each hypothesis gets a short coarse run (this
  /// loop with global_search off, global_schedule_m and global_iterations); the one with the
  /// most source points within global_inlier_distance_m of a target point (ties: the earlier
  /// hypothesis) then starts the full run.
  bool global_search = false;
  int yaw_hypotheses = 12;  ///< >= 1
  std::vector<double> global_schedule_m{std::numeric_limits<double>::infinity(), 0.5, 0.2};
  int global_iterations = 45;             ///< per hypothesis, over all its levels, >= 1
  double global_inlier_distance_m = 0.1;  ///< > 0
  /// The coarse runs and their score use every n-th source point (speed), >= 1.
  int global_subsample = 4;

  // --- stopping ---
  int max_iterations = 300;            ///< over all levels, >= 1
  int max_iterations_per_level = 60;   ///< >= 1
  double settle_translation_m = 1e-5;  ///< increment translation below this...
  double settle_rotation_rad = 1e-6;   ///< ...and rotation angle below this = settled
  int min_correspondences = 3;         ///< >= 3

  /// Ceres-style validation: false, and *why names the bad field and its value.
  bool is_valid(std::string* why = nullptr) const;
};

/// A RegistrationResult (termination: kTransform when settled at the last level, kMaxIterations,
/// kNoCorrespondences or kDegenerate; scores are PCL's fitness score, unlimited range unless
/// options say otherwise) plus what the robust loop knows.
struct RobustRegistrationResult : RegistrationResult {
  /// Correspondences kept in the last iteration / source points.
  double inlier_ratio = 0.0;
  /// Trim ratio used in the last iteration (1 without trimming).
  double overlap_ratio = 1.0;
  /// Maximum correspondence distance of the last level, metres.
  double final_max_distance_m = std::numeric_limits<double>::infinity();
  /// Weighted RMS of the last iteration's kept residuals, metres.
  double inlier_rms_m = 0.0;
  /// 6x6 covariance of the estimate. With EstimationCost::kPointToDistribution: the final
  /// point-to-distribution normal equations at the estimate with the final weights (normalised
  /// to mean 1), scaled by the variance factor: chi2 / (3n - 6) * H^-1 (same xi; see
  /// estimation_p2d.hpp). With point-to-point, from the final normal equations of that
  /// cost: sigma^2 (J^T W J)^-1 with J_i = [I, -[p_i]x] for a left perturbation
  /// T = exp(xi) T_hat, xi = (tx, ty, tz, rx, ry, rz) in the target frame (m, rad), W the
  /// normalised final weights and sigma^2 = sum w r^2 / (3n - 6). It treats residuals as
  /// independent, so it is a lower bound on the real error: on the real pair it understates it
  /// about 25-fold in standard deviation (docs/accuracy.md, "Uncertainty and the trust verdict").
  /// Zero if it could not be computed (fewer than 3 correspondences or singular).
  Mat6 covariance = Mat6::Zero();
};

/// The preset options of one of lmalign's own named strategies (PaperStrategy after
/// kMeanDistance; docs/accuracy.md): all use the default schedule (inf, 1, 0.5, 0.25, 0.1,
/// 0.05 m); `k` is used only by kRobustObsKnn's selection. kP2D and kRobustP2D use the
/// point-to-distribution cost (they need landmark covariances, see align_robust). Throws
/// InvalidArgument for a paper strategy (those run through align() with
/// RegistrationOptions::paper()).
RobustRegistrationOptions robust_strategy_options(PaperStrategy strategy, int k = 5);

/// A user's limits applied to a preset (what `lmalign align --max-iterations / --max-distance`
/// do to lmalign's own strategies): the iteration budget becomes `max_iterations` (>= 1; also
/// capping max_iterations_per_level), and the distance schedule is capped at `max_distance_m`
/// (> 0, metres; +inf = no cap): levels above it are replaced by one level at max_distance_m,
/// the finer ones are kept (e.g. inf, 1, 0.5, 0.25, 0.1, 0.05 capped at 0.3 gives 0.3, 0.25,
/// 0.1, 0.05). The global initialisation, if any, keeps its own schedule. Throws
/// InvalidArgument on a bad limit.
RobustRegistrationOptions with_limits(RobustRegistrationOptions options, int max_iterations,
                                      double max_distance_m);

struct PipelineSpec;
/// The engine's stages and settings that align_robust() runs (pipeline.hpp).
PipelineSpec robust_pipeline_spec(const RobustRegistrationOptions& options);

/// Aligns `source_points` to `target` from T_target_source_init with the robust loop:
/// per iteration, transform the source, find correspondences (nearest or weighted-kNN at the
/// current level's maximum distance), keep mutual ones, trim, weight by robust kernel times
/// target confidence, estimate the increment by weighted Umeyama (6-DoF) or the 4-DoF closed
/// form with IRLS re-weighting, compose T = dT * T. With global_search, first the yaw
/// hypotheses' coarse runs pick the start (see global_search); `iterations` then counts theirs
/// too. Deterministic for any thread count.
/// `source_covariances_m2`: one 3x3 position covariance per source point (m^2, in the frame of
/// `source_points`: rotate them with the points, C' = R C R^T), needed only by the
/// point-to-distribution cost (ignored otherwise; the target's come from its Map).
/// Throws InvalidArgument on invalid options, a non-finite guess or source point, an empty
/// source or target, a missing weight kind in the target, or, with kPointToDistribution, no or
/// mis-sized source covariances or a target without covariances.
RobustRegistrationResult align_robust(const Points3& source_points, const PreparedTarget& target,
                                      const RobustRegistrationOptions& options,
                                      const Isometry3& T_target_source_init = Isometry3::Identity(),
                                      const std::vector<Mat3>* source_covariances_m2 = nullptr);

}  // namespace lmalign
