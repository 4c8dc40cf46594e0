// Correspondence strategies: which target landmark each (transformed) source landmark is paired
// with in one ICP iteration (method.md §3).
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

/// A source-target pair. distance_sq_m2 is the squared distance at the time the pair was made
/// (PCL's pcl::Correspondence::distance, which PCL's convergence MSE averages).
struct Correspondence {
  PointIndex source_index = 0;
  PointIndex target_index = 0;
  double distance_sq_m2 = 0.0;
};
using Correspondences = std::vector<Correspondence>;

enum class CorrespondenceKind {
  /// Base ICP: the nearest target point (PCL CorrespondenceEstimation::determineCorrespondences).
  kNearest,
  /// The paper's Eq. 6: among the k nearest target points within the max distance, the one with
  /// the largest target weight; on equal weights the nearer one; none if no candidate has a
  /// positive weight. With k = 1 (and positive weights) identical to kNearest.
  kWeightedKnn,
};

std::string to_string(CorrespondenceKind kind);  ///< "nearest", "weighted_knn"

struct CorrespondenceOptions {
  CorrespondenceKind kind = CorrespondenceKind::kNearest;
  /// Neighbourhood size of kWeightedKnn (ignored by kNearest, which always takes 1). >= 1.
  int k = 5;
  /// Candidates farther than this (metres) are never paired. Infinite by default, as the paper.
  double max_distance_m = std::numeric_limits<double>::infinity();

  /// Ceres-style check: false and the bad field named in *why.
  bool is_valid(std::string* why = nullptr) const;
};

/// Finds correspondences against a fixed target. Queries run in parallel (OpenMP); the output is
/// identical for any thread count: pairs are listed in increasing source index.
class CorrespondenceFinder {
 public:
  /// `target` must outlive the finder. `target_weights` has one weight per target point (>= 0,
  /// finite); it may be empty for kNearest. Throws InvalidArgument on invalid options or
  /// mismatched/invalid weights.
  CorrespondenceFinder(const KdTree& target, std::vector<double> target_weights,
                       const CorrespondenceOptions& options);

  /// Replaces `out` with the correspondences of `source_points` (already transformed into the
  /// target frame, metres). Source points that are not finite get no correspondence.
  void find(const Points3& source_points, Correspondences& out) const;

  const CorrespondenceOptions& options() const { return options_; }

 private:
  const KdTree* target_;
  std::vector<double> weights_;
  CorrespondenceOptions options_;
  double max_distance_sq_m2_;
};

}  // namespace lmalign
