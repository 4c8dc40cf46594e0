// Closed-form rigid transformation estimation (method.md §3, step 3).
#pragma once

#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

namespace lmalign {

/// The rigid transform T_target_source minimising sum_i w_i |T * s_i - t_i|^2 over the given
/// correspondences: Umeyama (1991) / Kabsch without scale, with the reflection guard
/// (diag(1, 1, sign det) between the SVD factors), as PCL's TransformationEstimationSVD.
///
/// - source_points, target_points: metres, indexed by the correspondences' indices.
/// - weights: one per correspondence (>= 0), or nullptr for uniform.
/// Centroids are removed before the cross-covariance is accumulated (stable far from the origin).
/// Degenerate inputs (fewer than 3 non-collinear points) return a rotation that is one of the
/// minimisers; the translation still aligns the centroids.
/// Throws InvalidArgument if `correspondences` is empty, if the weights' count differs or their
/// sum is not positive.
Isometry3 estimate_rigid_transform(const Points3& source_points, const Points3& target_points,
                                   const Correspondences& correspondences,
                                   const std::vector<double>* weights = nullptr);

}  // namespace lmalign
