// Beyond the paper: the building blocks of the robust presets (configs/presets/robust_*.yaml,
// mutual.yaml), stages of the engine (pipeline.hpp): IRLS robust kernels, trimming to an overlap
// ratio given or estimated, mutual nearest neighbours.
//
// Frames: T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

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

}  // namespace lmalign
