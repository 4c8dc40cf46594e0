// Closed-form transformation estimation (method.md §3, step 3): Umeyama (1991) without scale, as
// the paper and PCL's TransformationEstimationSVD, and with scale (Sim(3), docs/scale.md).
#pragma once

#include <vector>

#include "lmalign/core/similarity.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

namespace lmalign {

/// What estimate_rigid_transform found out about its input.
struct EstimationReport {
  /// Singular values of the weighted cross-covariance H of the demeaned points, descending.
  Vec3 singular_values = Vec3::Zero();
  /// True when H has rank <= 1 (sigma_1 <= kDegenerateRatio * sigma_0, or H = 0): all points
  /// identical or on one line, on the source or the target side. The rotation is then not
  /// determined by the data; the estimate takes the smallest rotation among the minimisers
  /// (identity for rank 0; the shortest arc between the two line directions for rank 1).
  bool degenerate = false;

  static constexpr double kDegenerateRatio = 1e-10;
};

/// The rigid transform T_target_source minimising sum_i w_i |T * s_i - t_i|^2 over the given
/// correspondences: Umeyama (1991) / Kabsch without scale, with the reflection guard
/// (diag(1, 1, sign det) between the SVD factors), as PCL's TransformationEstimationSVD.
///
/// - source_points, target_points: metres, indexed by the correspondences' indices.
/// - weights: one per correspondence (>= 0), or nullptr for uniform.
/// Centroids are removed before the cross-covariance is accumulated (stable far from the origin).
/// Degenerate inputs (all points identical or collinear on either side) return the smallest
/// rotation among the minimisers, deterministically; the translation still aligns the centroids.
/// The result is always finite with a proper rotation (det +1) when the inputs are finite.
/// `report`, if given, receives the singular values and the degeneracy flag.
/// Throws InvalidArgument if `correspondences` is empty, if the weights' count differs, a weight
/// is negative or not finite, or their sum is not positive, or if the input points are so large
/// that the estimate overflows (|coordinate| around 1e150 m and beyond).
Isometry3 estimate_rigid_transform(const Points3& source_points, const Points3& target_points,
                                   const Correspondences& correspondences,
                                   const std::vector<double>* weights = nullptr,
                                   EstimationReport* report = nullptr);

/// The same with the scale (Sim(3)): the similarity p_target = c R p_source + t minimising
/// sum_i w_i |c R s_i + t - t_i|^2, Umeyama's eq. 42 c = trace(D Sigma) / sigma_s^2 (as COLMAP's
/// model_aligner estimates its Sim3d). The rotation is estimate_rigid_transform's (the same
/// reflection guard and degenerate cases); the scale is 1 when the source points coincide.
/// Throws as estimate_rigid_transform.
Similarity3 estimate_similarity_transform(const Points3& source_points,
                                          const Points3& target_points,
                                          const Correspondences& correspondences,
                                          const std::vector<double>* weights = nullptr,
                                          EstimationReport* report = nullptr);

}  // namespace lmalign
