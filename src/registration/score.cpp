#include "lmalign/registration/score.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <omp.h>

#include "lmalign/core/first_exception.hpp"

namespace lmalign {

namespace {

// Source points are scored in blocks: squared distances computed in parallel into a fixed
// buffer, then added serially in source order (the same sum as one serial loop, for any thread
// count, without a buffer the size of the map).
constexpr std::size_t kBlock = 4096;

template <class NearestBlock>
FitnessScore blocked_score(std::size_t n, double max_range_m, NearestBlock&& nearest_block) {
  const double max_sq = std::isinf(max_range_m) || max_range_m > 1e150
                            ? std::numeric_limits<double>::infinity()
                            : max_range_m * max_range_m;
  std::array<double, kBlock> d2;
  FitnessScore score;
  double sum = 0.0;
  for (std::size_t begin = 0; begin < n; begin += kBlock) {
    const std::size_t end = std::min(n, begin + kBlock);
    nearest_block(begin, end, d2.data());  // +inf: no neighbour
    for (std::size_t i = 0; i < end - begin; ++i) {
      const double v = d2[i];
      if (!std::isinf(v) && v <= max_sq) {
        sum += v;
        ++score.num_scored;
      }
    }
  }
  if (score.num_scored > 0) score.mean_sq_m2 = sum / static_cast<double>(score.num_scored);
  return score;
}

}  // namespace

FitnessScore fitness_score(const Points3& source_points, const KdTree& target,
                           const Isometry3& T_target_source, double max_range_m) {
  // Exactly transform_points(): R * p + t.
  const Mat3 R = T_target_source.linear();
  const Vec3 t = T_target_source.translation();
  return blocked_score(
      source_points.size(), max_range_m, [&](std::size_t begin, std::size_t end, double* d2) {
        FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for proc_bind(close) schedule(static)
        for (std::ptrdiff_t i = static_cast<std::ptrdiff_t>(begin);
             i < static_cast<std::ptrdiff_t>(end); ++i) {
          error.capture([&] {
            const Vec3 p = R * source_points[static_cast<std::size_t>(i)] + t;
            PointIndex idx = 0;
            double dist_sq = 0.0;
            d2[static_cast<std::size_t>(i) - begin] = target.nearest(p, &idx, &dist_sq)
                                                          ? dist_sq
                                                          : std::numeric_limits<double>::infinity();
          });
        }
        error.rethrow();
      });
}

FitnessScore fitness_score(const Points3& source_points, const CorrespondenceFinder& finder,
                           const Isometry3& T_target_source, double max_range_m,
                           CorrespondenceWorkspace& workspace) {
  return blocked_score(
      source_points.size(), max_range_m, [&](std::size_t begin, std::size_t end, double* d2) {
        finder.nearest_sq_distances(source_points, T_target_source, begin, end, d2, workspace);
      });
}

}  // namespace lmalign
