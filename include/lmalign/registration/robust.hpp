// Beyond the paper: an accurate ICP for partial-overlap landmark maps, the robust presets' loop
// (configs/presets/robust_*.yaml, mutual.yaml). Correspondence rejection (a maximum distance on a
// shrinking schedule, trimming to an overlap ratio given or estimated, mutual nearest
// neighbours), each combinable with the paper's weighted-kNN selection; weighted Umeyama with
// IRLS robust kernels times landmark confidences; optional 4-DoF (x, y, z, yaw) estimation; an
// optional global yaw search for far starts. RobustRegistrationOptions is the C++ convenience for
// those stages' settings: align_robust() runs the engine (pipeline.hpp) with
// robust_pipeline_spec().
//
// Frames: the result is T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/registration/estimation_4dof.hpp"
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
inline constexpr EnumName<RobustKernel> kRobustKernelNames[] = {
    {RobustKernel::kNone, "none"},
    {RobustKernel::kHuber, "huber"},
    {RobustKernel::kCauchy, "cauchy"},
    {RobustKernel::kGemanMcClure, "geman_mcclure"}};
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

  // --- global search (no ground truth used) ---
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
  /// 6x6 covariance of the estimate from the final normal equations of the point-to-point
  /// cost: sigma^2 (J^T W J)^-1 with J_i = [I, -[p_i]x] for a left perturbation
  /// T = exp(xi) T_hat, xi = (tx, ty, tz, rx, ry, rz) in the target frame (m, rad), W the
  /// normalised final weights and sigma^2 = sum w r^2 / (3n - 6). It treats residuals as
  /// independent, so it is a lower bound on the real error (docs/accuracy.md, "Uncertainty and
  /// the trust verdict"). Zero if it could not be computed (fewer than 3 correspondences or
  /// singular).
  Mat6 covariance = Mat6::Zero();
};

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
/// Throws InvalidArgument on invalid options, a non-finite guess or source point, an empty
/// source or target, or a missing weight kind in the target.
RobustRegistrationResult align_robust(
    const Points3& source_points, const PreparedTarget& target,
    const RobustRegistrationOptions& options,
    const Isometry3& T_target_source_init = Isometry3::Identity());

}  // namespace lmalign
