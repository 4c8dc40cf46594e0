// Uncertainty of an estimated rigid transform, and a trustworthiness verdict.
//
// Parametrisation (Barfoot, "State Estimation for Robotics", §7.1): a perturbation
// xi = (rho [m], phi [rad]) applied on the left, in the target frame:
//   T_target_source = Exp(xi) * T_hat.
// The covariance comes from the point-to-point normal equations at the solution: residuals
// r_i = q_i - T p_i with Jacobian [I, -[x_i]x] (x_i = T_hat p_i), H = sum J^T J, and the
// per-axis residual variance sigma^2 = sum |r_i|^2 / (3 n - 6): Cov = sigma^2 H^-1. It assumes
// independent isotropic residuals and correct correspondences, so it is a lower bound when the
// correspondences are wrong (docs/accuracy.md measures how it holds on the real pair).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

/// The 6x6 covariance of a transform estimate (see the file comment).
struct PoseCovariance {
  /// Covariance of xi = (rho [m], phi [rad]), rows/cols 0-2 translation, 3-5 rotation.
  Mat6 covariance = Mat6::Zero();
  /// With a free scale (Sim(3)): the 7x7 covariance of (rho [target units], phi [rad], sigma =
  /// log scale [1]) as a left perturbation about the target origin; `covariance` is then its
  /// top-left 6x6 block (the marginal of the rotation and translation).
  bool has_scale = false;
  Mat7 covariance_7x7 = Mat7::Zero();
  double sigma_m = 0.0;  ///< per-axis residual standard deviation, metres
  std::size_t num_correspondences = 0;
  /// False when the normal equations are singular (fewer than 3 correspondences, or all
  /// correspondences on a line): `covariance` is then zero and must not be used.
  bool valid = false;
  /// Standard deviations of the translation (m) and of the rotation (deg) along their worst axes.
  double translation_sd_m() const;
  double rotation_sd_deg() const;
};

/// Covariance of the transform that maps `moved_source[c.source_index]` (already transformed by
/// the estimate, metres, target frame) onto `target_points[c.target_index]`, from the
/// correspondences of the final iteration. With `weights` (one per correspondence, >= 0, e.g. the
/// final IRLS weights), they are normalised to mean 1 and enter both H = sum w J^T J and
/// sigma^2 = sum w |r|^2 / (3n - 6). `with_scale`: the 7x7 with sigma = log scale too
/// (covariance_7x7; sigma^2 over 3n - 7). Throws InvalidArgument if an index is out of range or
/// the weights do not match the correspondences.
PoseCovariance point_to_point_covariance(const Points3& moved_source, const Points3& target_points,
                                         const Correspondences& correspondences,
                                         const std::vector<double>* weights = nullptr,
                                         bool with_scale = false);

/// The left-perturbation error of an estimate: xi with T_est = Exp(xi) T_true, to first order
/// (rho = translation of T_est T_true^-1, phi = its rotation vector).
Vec6 pose_error_twist(const Isometry3& T_est, const Isometry3& T_true);
/// The same for a similarity: the estimate p -> T_est (scale_est p) against T_true (scale 1),
/// xi = (rho, phi, sigma = log scale_est) of S_est S_true^-1 about the target origin.
Vec7 similarity_error_twist(const Isometry3& T_est, double scale_est, const Isometry3& T_true);

/// The larger of two covariances, direction by direction (a Loewner upper bound of both that
/// keeps `floor` wherever `other` is smaller): with floor = L L^T, the eigenvalues of
/// L^-1 other L^-T are raised to at least 1 and mapped back. Used to widen a model covariance by
/// an empirical one without ever narrowing it (p2d_cluster_covariance, the adaptive default's
/// half-sample covariance). Returns `floor` unchanged when it is not positive definite or the
/// result is not finite. Both 6x6 (or both 7x7, with the scale), any units as long as they
/// agree.
Mat6 covariance_max(const Mat6& floor, const Mat6& other);
Mat7 covariance_max(const Mat7& floor, const Mat7& other);

/// Normalised estimation error squared e^T Cov^-1 e (6 dof: its mean is 6 when the covariance
/// is calibrated). +inf when the covariance is not valid.
double nees(const Vec6& error, const PoseCovariance& covariance);

/// When to call a result trustworthy. A right alignment puts the source landmarks that lie in
/// the overlap (within overlap_distance_m of a target landmark) on target landmarks (within
/// inlier_distance_m); a wrong one leaves many of them between. So the verdict asks for a high
/// inlier ratio (inliers / overlap), which does not depend on how much the maps overlap, plus a
/// minimum overlap and a small covariance. Defaults were chosen on the real pair's basin sweep
/// (docs/accuracy.md gives the precision and recall).
struct TrustOptions {
  double inlier_distance_m = 0.05;   ///< > 0
  double overlap_distance_m = 0.20;  ///< >= inlier_distance_m
  double min_inlier_ratio = 0.75;    ///< inliers / overlap, in [0, 1]
  double min_inlier_fraction = 0.1;  ///< inliers / all source landmarks, in [0, 1]
  double max_translation_sd_m = 0.02;
  double max_rotation_sd_deg = 1.0;
  bool is_valid(std::string* why = nullptr) const;
};

/// The verdict and what it was decided on.
struct TrustVerdict {
  bool trustworthy = false;
  double inlier_fraction = 0.0;   ///< source landmarks within inlier_distance_m, of all
  double overlap_fraction = 0.0;  ///< source landmarks within overlap_distance_m, of all
  double translation_sd_m = 0.0;
  double rotation_sd_deg = 0.0;
  std::string reason;  ///< why not, or "ok"
};

/// Judges the estimate T_target_source: nearest target landmark of every transformed source
/// landmark, the inlier and overlap fractions, the covariance on the inliers (returned in
/// *inlier_covariance if not null), then the rules above. Throws InvalidArgument on invalid
/// options or an empty source.
TrustVerdict judge_alignment(const Points3& source_points, const KdTree& target,
                             const Isometry3& T_target_source, const TrustOptions& options = {},
                             PoseCovariance* inlier_covariance = nullptr);

}  // namespace lmalign
