#include <omp.h>

#include <random>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"

namespace lmalign {
namespace {

Isometry3 random_transform(std::mt19937& rng) {
  std::uniform_real_distribution<double> a(-180.0, 180.0), t(-5.0, 5.0);
  return pose_from_xyz_rpy_deg(t(rng), t(rng), t(rng), a(rng), a(rng) / 2.0, a(rng));
}

Correspondences identity_pairs(std::size_t n) {
  Correspondences c(n);
  for (std::size_t i = 0; i < n; ++i) c[i] = {PointIndex(i), PointIndex(i), 0.0};
  return c;
}

TEST(EstimateRigidTransform, RecoversRandomTransformsExactlyOnNoiselessPoints) {
  std::mt19937 rng(2024);
  std::normal_distribution<double> g(0.0, 2.0);
  for (int trial = 0; trial < 50; ++trial) {
    Points3 src(4 + trial * 3);
    for (auto& p : src) p = Vec3(g(rng), g(rng), g(rng)) + Vec3(100, -50, 20);  // off-origin
    const Isometry3 T_true = random_transform(rng);
    const Points3 tgt = transform_points(T_true, src);
    const Isometry3 T = estimate_rigid_transform(src, tgt, identity_pairs(src.size()));
    const TransformError e = transform_error(T, T_true);
    EXPECT_LT(e.rotation_deg, 1e-6) << "trial " << trial;
    EXPECT_LT(e.translation_m, 1e-9) << "trial " << trial;
    EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  }
}

TEST(EstimateRigidTransform, NeverReturnsAReflection) {
  // The target is the mirror image of the source: the unconstrained optimum is a reflection.
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  Points3 src(30), tgt(30);
  for (std::size_t i = 0; i < src.size(); ++i) {
    src[i] = Vec3(g(rng), g(rng), g(rng));
    tgt[i] = Vec3(src[i].x(), src[i].y(), -src[i].z());
  }
  const Isometry3 T = estimate_rigid_transform(src, tgt, identity_pairs(src.size()));
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  EXPECT_TRUE((T.linear() * T.linear().transpose()).isApprox(Mat3::Identity(), 1e-12));
}

TEST(EstimateRigidTransform, WeightsSilenceOutliers) {
  std::mt19937 rng(4);
  std::normal_distribution<double> g(0.0, 1.0);
  Points3 src(40);
  for (auto& p : src) p = Vec3(g(rng), g(rng), g(rng));
  const Isometry3 T_true = random_transform(rng);
  Points3 tgt = transform_points(T_true, src);
  std::vector<double> w(src.size(), 1.0);
  for (std::size_t i = 0; i < 10; ++i) {
    tgt[i] += Vec3(5, -3, 2);  // gross outliers
    w[i] = 0.0;
  }
  const Isometry3 T = estimate_rigid_transform(src, tgt, identity_pairs(src.size()), &w);
  EXPECT_LT(transform_error(T, T_true).translation_m, 1e-9);
  // Without the weights the outliers pull the estimate away.
  const Isometry3 T_unweighted = estimate_rigid_transform(src, tgt, identity_pairs(src.size()));
  EXPECT_GT(transform_error(T_unweighted, T_true).translation_m, 0.1);
}

TEST(EstimateRigidTransform, RejectsEmptyAndBadWeights) {
  const Points3 p = {Vec3(0, 0, 0)};
  EXPECT_THROW(estimate_rigid_transform(p, p, {}), InvalidArgument);
  const std::vector<double> zero = {0.0};
  EXPECT_THROW(estimate_rigid_transform(p, p, identity_pairs(1), &zero), InvalidArgument);
  const std::vector<double> two = {1.0, 1.0};
  EXPECT_THROW(estimate_rigid_transform(p, p, identity_pairs(1), &two), InvalidArgument);
}

TEST(EstimateRigidTransform, BlockedSumsAreTheSameForAnyThreadCountAndMatchTheTruth) {
  // Enough correspondences for several blocks (parallel sums), with noise and weights.
  std::mt19937 rng(77);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.1, 3.0);
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.3, -0.2, 0.1, 4.0, -2.0, 25.0);
  for (std::size_t n : {511u, 513u, 4000u, 60000u}) {  // 60,000: parallel blocks
    Points3 src(n), tgt(n);
    std::vector<double> w(n);
    for (std::size_t i = 0; i < n; ++i) {
      src[i] = Vec3(g(rng), g(rng), 0.3 * g(rng));
      tgt[i] = T_true * src[i] + 1e-3 * Vec3(g(rng), g(rng), g(rng));
      w[i] = u(rng);
    }
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const Isometry3 one = estimate_rigid_transform(src, tgt, identity_pairs(n), &w);
    omp_set_num_threads(2);
    const Isometry3 two = estimate_rigid_transform(src, tgt, identity_pairs(n), &w);
    omp_set_num_threads(saved);
    EXPECT_TRUE(one.matrix() == two.matrix()) << "n = " << n;  // to the bit
    const TransformError e = transform_error(one, T_true);
    EXPECT_LT(e.rotation_deg, 0.05) << "n = " << n;
    EXPECT_LT(e.translation_m, 5e-4) << "n = " << n;
  }
}

}  // namespace
}  // namespace lmalign

namespace lmalign {
namespace {

TEST(EstimateRigidTransform, CollinearNearlyOppositeLinesStillGiveARotation) {
  // Rank-1 cross-covariance whose singular vectors are nearly opposite (the two lines differ by
  // 180 degrees minus a few microradians): the smallest rotation between them is built from a
  // quaternion whose norm rounding can move off 1 (found by fuzz_map_reader at 1e9 m).
  for (double tiny_rad : {2e-6, 4e-6, 5e-6, 8e-6, 2e-5}) {
    const Vec3 a = Vec3(1.0, 2.0, 0.5).normalized();
    const Vec3 b = -(Eigen::AngleAxisd(tiny_rad, Vec3(0.3, -1.0, 2.0).normalized()) * a);
    Points3 src, tgt;
    for (int i = 0; i < 6; ++i) {
      src.push_back(1e9 * Vec3::Ones() + 0.25 * i * a);
      tgt.push_back(-3.0 * Vec3::Ones() + 0.25 * i * b);
    }
    EstimationReport report;
    const Isometry3 T =
        estimate_rigid_transform(src, tgt, identity_pairs(src.size()), nullptr, &report);
    EXPECT_TRUE(report.degenerate);
    const Mat3 R = T.linear();
    EXPECT_LT((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-12) << tiny_rad;
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12) << tiny_rad;
  }
}

}  // namespace
}  // namespace lmalign
