// Point-to-distribution estimation (issue 7): the rigid transform that best explains fixed
// correspondences when both landmarks of a pair carry a SLAM position covariance.
//
// Cost (Segal, Haehnel & Thrun 2009, "Generalized-ICP", Eq. 2, with the maps' own landmark
// covariances in place of GICP's neighbourhood ones):
//   E(T) = sum_i w_i r_i^T Omega_i r_i,   r_i = q_i - (R p_i + t),
//   Omega_i = (C_t,i + R C_s,i R^T + sigma_floor^2 I)^-1,
// with q_i the target landmark, p_i the source landmark (its own frame), C_t,i its target
// covariance (target frame), C_s,i the source one (source frame), w_i >= 0 a per-pair weight.
//
// Solved by Gauss-Newton on SE(3) (Barfoot, "State Estimation for Robotics", §7.1-7.3) with the
// same left perturbation as uncertainty.hpp: T = Exp(xi) T_hat, xi = (rho [m], phi [rad]) in the
// target frame, where Exp(xi) rotates by exp(phi^) and then translates by rho (the convention
// of pose_error_twist()). Each step linearises r_i about x_i = T_hat p_i:
//   r_i(xi) ~= r_i - rho + [x_i]x phi,  J_i = [-I, [x_i]x],
// solves (sum w J^T Omega J) xi = -sum w J^T Omega r, and applies T = Exp(xi) T_hat. As in GICP,
// Omega_i is recomputed at every step with the current rotation but not differentiated.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

namespace lmalign {

struct PointToDistributionOptions {
  /// Gauss-Newton steps, >= 0. 0 only evaluates the cost and the covariance at T_init.
  int max_iterations = 3;
  /// Stop early once a step moves less than this (|rho| in m plus |phi| in rad), >= 0.
  double step_tolerance = 1e-12;
  /// Covariance floor, metres, finite and >= 1e-9 (1 nm; below, its inverse square could
  /// overflow the normal equations): sigma_floor^2 I is added to every combined
  /// covariance C_t + R C_s R^T, so that zero, tiny or rank-deficient SLAM covariances (a
  /// landmark seen from one direction is nearly flat) cannot make Omega singular or let one
  /// landmark dominate. 5 mm: about the smallest across-ray standard deviation of the real
  /// maps' landmarks (~4-5 mm; docs/confidence.md).
  double covariance_floor_m = 0.005;

  /// Ceres-style validation: false, and *why names the bad field and its value.
  bool is_valid(std::string* why = nullptr) const;
};

/// What estimate_point_to_distribution returns.
struct PointToDistributionResult {
  /// The estimate T_target_source (always finite; T_init when degenerate).
  Isometry3 T_target_source = Isometry3::Identity();
  /// H^-1 of the normal equations at the estimate, H = sum w_i J_i^T Omega_i J_i with the
  /// weights normalised to mean 1: the covariance of xi = (rho [m], phi [rad]) (rows/cols 0-2
  /// translation, 3-5 rotation) IF the covariances are calibrated and the pairs independent.
  /// Unscaled; multiply by variance_factor for the a-posteriori estimate. Zero when degenerate.
  Mat6 covariance = Mat6::Zero();
  /// chi2 / (3n - 6), chi2 = sum w_i r_i^T Omega_i r_i at the estimate (normalised weights):
  /// about 1 when the covariances describe the residuals; 0 if n <= 2.
  double variance_factor = 0.0;
  double chi2 = 0.0;   ///< at the estimate, normalised weights (dimensionless)
  int iterations = 0;  ///< Gauss-Newton steps taken
  std::size_t num_correspondences = 0;
  /// True with fewer than 3 correspondences or a singular H (e.g. all points on one line): the
  /// estimate is then the last finite one (T_init if the first step failed) and covariance zero.
  bool degenerate = false;
};

/// Minimises the cost of the file comment over T_target_source, starting from T_init.
///
/// - source_points (metres, source frame), target_points (metres, target frame): indexed by the
///   correspondences' source_index / target_index.
/// - source_covariances_m2: one 3x3 covariance (m^2, source frame) per source point;
///   target_covariances_m2: one per target point (m^2, target frame). Symmetric PSD expected
///   (only finiteness is checked). Omega is positive definite whatever their size: a combined
///   covariance whose trace exceeds 1e8 floor^2 (or that is not positive definite) is inverted
///   through its eigendecomposition, eigenvalues raised to at least floor^2, so that huge
///   variances carry no information instead of round-off (docs/robustness.md).
/// - weights: one per correspondence (>= 0, finite, positive sum), or nullptr for uniform; e.g.
///   IRLS kernel weight times landmark confidence. Scale-free: normalised to mean 1.
/// Deterministic. Never returns NaN for finite inputs: degenerate input (fewer than 3
/// correspondences, singular normal equations) returns a finite estimate with `degenerate` set.
/// Throws InvalidArgument on invalid options, covariance or weight counts that do not match,
/// an index out of range, a non-finite covariance, or a negative, non-finite or all-zero weight.
PointToDistributionResult estimate_point_to_distribution(
    const Points3& source_points, const Points3& target_points,
    const Correspondences& correspondences, const std::vector<Mat3>& source_covariances_m2,
    const std::vector<Mat3>& target_covariances_m2, const std::vector<double>* weights = nullptr,
    const PointToDistributionOptions& options = {},
    const Isometry3& T_init = Isometry3::Identity());

}  // namespace lmalign
