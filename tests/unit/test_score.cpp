#include <limits>

#include <gtest/gtest.h>

#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/score.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

double brute_force_score(const Points3& src, const Points3& tgt, const Isometry3& T,
                         double max_range_m, std::size_t* n) {
  double sum = 0;
  *n = 0;
  for (const Vec3& s : src) {
    const Vec3 p = T * s;
    double best = std::numeric_limits<double>::infinity();
    for (const Vec3& t : tgt) best = std::min(best, (p - t).squaredNorm());
    if (best <= max_range_m * max_range_m) {
      sum += best;
      ++*n;
    }
  }
  return *n ? sum / static_cast<double>(*n) : std::numeric_limits<double>::infinity();
}

TEST(FitnessScore, EqualsBruteForce) {
  const Points3 tgt = test::room_points(1500, 21);
  const Points3 src = test::room_points(900, 22);
  const KdTree tree(tgt);
  const Isometry3 T = pose_from_xyz_rpy_deg(0.2, -0.1, 0.05, 3, -2, 15);
  for (double range : {std::numeric_limits<double>::infinity(), 0.05, 0.02}) {
    std::size_t n_bf = 0;
    const double bf = brute_force_score(src, tgt, T, range, &n_bf);
    const FitnessScore s = fitness_score(src, tree, T, range);
    EXPECT_EQ(s.num_scored, n_bf) << "range " << range;
    EXPECT_NEAR(s.mean_sq_m2, bf, 1e-15 + 1e-12 * bf) << "range " << range;
  }
}

TEST(FitnessScore, NothingInRangeIsInfinite) {
  const KdTree tree(Points3{Vec3(0, 0, 0)});
  const FitnessScore s = fitness_score({Vec3(10, 0, 0)}, tree, Isometry3::Identity(), 1.0);
  EXPECT_EQ(s.num_scored, 0u);
  EXPECT_TRUE(std::isinf(s.mean_sq_m2));
  // Exactly at range counts (PCL compares with <=).
  EXPECT_EQ(fitness_score({Vec3(1, 0, 0)}, tree, Isometry3::Identity(), 1.0).num_scored, 1u);
}

}  // namespace
}  // namespace lmalign
