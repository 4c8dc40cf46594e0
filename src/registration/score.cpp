#include "lmalign/registration/score.hpp"

#include <cmath>
#include <vector>

#include <omp.h>

namespace lmalign {

FitnessScore fitness_score(const Points3& source_points, const KdTree& target,
                           const Isometry3& T_target_source, double max_range_m) {
  const double max_sq = std::isinf(max_range_m) || max_range_m > 1e150
                            ? std::numeric_limits<double>::infinity()
                            : max_range_m * max_range_m;
  const std::size_t n = source_points.size();
  // Per-point values computed in parallel, summed serially in index order: deterministic.
  std::vector<double> d2(n, -1.0);
  const Mat3 R = T_target_source.linear();
  const Vec3 t = T_target_source.translation();
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    const Vec3 p = R * source_points[static_cast<std::size_t>(i)] + t;
    PointIndex idx = 0;
    double dist_sq = 0.0;
    if (p.allFinite() && target.nearest(p, &idx, &dist_sq) && dist_sq <= max_sq) d2[i] = dist_sq;
  }
  FitnessScore score;
  double sum = 0.0;
  for (double v : d2) {
    if (v >= 0.0) {
      sum += v;
      ++score.num_scored;
    }
  }
  if (score.num_scored > 0) score.mean_sq_m2 = sum / static_cast<double>(score.num_scored);
  return score;
}

}  // namespace lmalign
