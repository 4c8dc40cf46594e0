// The 6x6 covariance of an estimate (lmalign/registration/uncertainty.hpp): calibrated on
// synthetic data with known correspondences and isotropic noise (NEES against chi-square
// bounds), singular on degenerate geometry; and the trust verdict's rules.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/uncertainty.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

TEST(Uncertainty, CovarianceIsCalibratedOnIsotropicNoise) {
  const Points3 target = test::room_points(300, 17);
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.3, -0.2, 0.1, 4, -3, 25);
  const Points3 clean_source = transform_points(T_true.inverse(), target);
  Correspondences c;
  for (std::size_t i = 0; i < target.size(); ++i) {
    c.push_back({static_cast<PointIndex>(i), static_cast<PointIndex>(i), 0.0});
  }
  std::mt19937 rng(99);
  std::normal_distribution<double> g(0.0, 0.01);  // 1 cm per axis
  const int trials = 300;
  double sum = 0.0;
  for (int t = 0; t < trials; ++t) {
    Points3 noisy = target;
    for (Vec3& p : noisy) p += Vec3(g(rng), g(rng), g(rng));
    const Isometry3 T = estimate_rigid_transform(clean_source, noisy, c);
    const Points3 moved = transform_points(T, clean_source);
    const PoseCovariance cov = point_to_point_covariance(moved, noisy, c);
    ASSERT_TRUE(cov.valid);
    EXPECT_NEAR(cov.sigma_m, 0.01, 0.0015);
    sum += nees(pose_error_twist(T, T_true), cov);
  }
  // Mean of 300 chi-square(6) draws: 99.9% bounds of chi2(1800) / 300.
  const double mean = sum / trials;
  EXPECT_GT(mean, 5.35);
  EXPECT_LT(mean, 6.65);
}

TEST(Uncertainty, SingularOnALineAndTooFewPoints) {
  Points3 line;
  Correspondences c;
  for (int i = 0; i < 20; ++i) {
    line.emplace_back(0.1 * i, 0.05 * i, 1.0);
    c.push_back({static_cast<PointIndex>(i), static_cast<PointIndex>(i), 0.0});
  }
  const PoseCovariance on_line = point_to_point_covariance(line, line, c);
  EXPECT_FALSE(on_line.valid);
  EXPECT_TRUE(std::isinf(nees(Vec6::Zero(), on_line)));
  c.resize(2);
  EXPECT_FALSE(point_to_point_covariance(line, line, c).valid);
  c.push_back({100, 0, 0.0});
  EXPECT_THROW(point_to_point_covariance(line, line, c), InvalidArgument);
}

TEST(Uncertainty, TrustVerdictTellsRightFromWrongAlignments) {
  // Target: a room; source: 70% of it (partial overlap), 3 mm noise, at a known transform.
  const Points3 target = test::room_points(1500, 3);
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 0.003);
  Points3 seen;
  for (const Vec3& q : target) {
    if (q.x() < 2.8) seen.push_back(q + Vec3(g(rng), g(rng), g(rng)));
  }
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.5, -0.4, 0.1, 2, -1, 40);
  const Points3 source = transform_points(T_true.inverse(), seen);
  const KdTree tree(target);

  PoseCovariance cov;
  const TrustVerdict right = judge_alignment(source, tree, T_true, {}, &cov);
  EXPECT_TRUE(right.trustworthy) << right.reason;
  EXPECT_GT(right.inlier_fraction, 0.95);  // every seen landmark is in the overlap
  EXPECT_TRUE(cov.valid);
  EXPECT_LT(right.rotation_sd_deg, 0.1);

  // 8 degrees and 10 cm off: the overlap is still there, but its landmarks do not coincide.
  const TrustVerdict wrong =
      judge_alignment(source, tree, pose_from_xyz_rpy_deg(0.1, 0, 0, 0, 0, 8) * T_true);
  EXPECT_FALSE(wrong.trustworthy);
  EXPECT_NE(wrong.reason.find("inlier ratio"), std::string::npos) << wrong.reason;
  // Far away: no overlap at all.
  const TrustVerdict away =
      judge_alignment(source, tree, pose_from_xyz_rpy_deg(20, 0, 0, 0, 0, 0) * T_true);
  EXPECT_FALSE(away.trustworthy);
  EXPECT_NE(away.reason.find("inlier fraction"), std::string::npos) << away.reason;
  // An impossible uncertainty bound rejects even the right one, naming it.
  TrustOptions strict;
  strict.max_rotation_sd_deg = 1e-9;
  const TrustVerdict shaky = judge_alignment(source, tree, T_true, strict);
  EXPECT_FALSE(shaky.trustworthy);
  EXPECT_NE(shaky.reason.find("rotation sd"), std::string::npos);
  strict.overlap_distance_m = 0.01;  // below the inlier distance
  EXPECT_THROW(judge_alignment(source, tree, T_true, strict), InvalidArgument);
  EXPECT_THROW(judge_alignment({}, tree, T_true), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
