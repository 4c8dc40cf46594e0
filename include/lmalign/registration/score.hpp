// The paper's alignment score (its Eq. 5 as its tables computed it; method.md §4): PCL's
// Registration::getFitnessScore().
#pragma once

#include <cstddef>
#include <limits>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

struct FitnessScore {
  /// Mean squared distance (m^2) from each transformed source point to its nearest target point,
  /// over the points within range. +inf if no point is within range (PCL returns DBL_MAX).
  double mean_sq_m2 = std::numeric_limits<double>::infinity();
  /// How many source points were within range and entered the mean.
  std::size_t num_scored = 0;
};

/// PCL getFitnessScore(max_range): apply T_target_source to the ORIGINAL source points, find each
/// one's nearest target point, and average the squared distances of those with
/// squared distance <= max_range_m^2. Note the unit: PCL compares its max_range argument against
/// the squared distance; lmalign takes a distance in metres and squares it (infinite by default).
/// Weights never enter the score. Parallel; the sum runs serially in source order, so the value
/// is identical for any thread count.
FitnessScore fitness_score(const Points3& source_points, const KdTree& target,
                           const Isometry3& T_target_source,
                           double max_range_m = std::numeric_limits<double>::infinity());

/// The same value, bit for bit, with the nearest neighbours served by `finder`'s exact reuse
/// cache in `workspace` (see CorrespondenceWorkspace) and refreshed there where they are searched
/// again: the ICP loop's score. Allocates nothing once the workspace is warm.
FitnessScore fitness_score(const Points3& source_points, const CorrespondenceFinder& finder,
                           const Isometry3& T_target_source, double max_range_m,
                           CorrespondenceWorkspace& workspace);

}  // namespace lmalign
