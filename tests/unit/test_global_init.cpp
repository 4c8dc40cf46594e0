// Global initialisation (lmalign/registration/global_init.hpp) against known answers: a synthetic
// room seen twice with partial overlap, outliers and noise, displaced by any yaw and metres of
// translation.
#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <random>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/global_init.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

// Target: the room. Source: 70% of the same landmarks (a slab of the room: partial overlap),
// with 3 mm noise, plus 15% outliers, expressed in a source frame displaced by T_target_source^-1.
struct Pair {
  Points3 source, target;
  Isometry3 T_target_source;
};

Pair make_pair(double yaw_deg, double x_m, double y_m, std::uint32_t seed) {
  Pair p;
  p.target = test::room_points(1500, seed);
  std::mt19937 rng(seed + 1);
  std::normal_distribution<double> noise(0.0, 0.003);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Points3 in_target_frame;
  for (const Vec3& q : p.target) {
    if (q.x() > 2.8) continue;  // the source session saw x <= 2.8 m only (about 70%)
    in_target_frame.push_back(q + Vec3(noise(rng), noise(rng), noise(rng)));
  }
  const std::size_t outliers = in_target_frame.size() * 15 / 100;
  for (std::size_t i = 0; i < outliers; ++i) {
    in_target_frame.emplace_back(4.0 * u(rng), 3.0 * u(rng), 2.5 * u(rng));
  }
  p.T_target_source = pose_from_xyz_rpy_deg(x_m, y_m, 0.05, 0, 0, yaw_deg);
  p.source = transform_points(p.T_target_source.inverse(), in_target_frame);
  return p;
}

TEST(GlobalInit, RecoversAnyYawAndMetresOfTranslationWithPartialOverlapAndOutliers) {
  int case_index = 0;
  for (double yaw : {-170.0, -95.0, -20.0, 45.0, 135.0, 180.0}) {
    const double x = case_index % 2 == 0 ? 2.5 : -1.5;
    const double y = case_index % 3 == 0 ? -2.0 : 1.0;
    const Pair p = make_pair(yaw, x, y, 300 + static_cast<std::uint32_t>(case_index));
    const PreparedTarget target(p.target);
    const GlobalInitResult r = global_align(p.source, target);
    const TransformError e = transform_error(r.T_target_source, p.T_target_source);
    EXPECT_LT(e.rotation_deg, 0.5) << "yaw " << yaw;
    EXPECT_LT(e.translation_m, 0.02) << "yaw " << yaw;
    // About 85% of the source landmarks are real (15% outliers): the inliers are found.
    EXPECT_GT(r.inlier_fraction, 0.75) << "yaw " << yaw;
    EXPECT_LT(r.inlier_rms_m, 0.02);
    EXPECT_TRUE(r.T_target_source.matrix().allFinite());
    ASSERT_EQ(r.hypotheses.size(), 36u);  // every 10 degrees
    ++case_index;
  }
}

TEST(GlobalInit, UpAxisIsAnOption) {
  // The same problem with y as the up axis: rotate everything so that z becomes y.
  const Pair p = make_pair(120.0, 1.0, -2.0, 77);
  const Isometry3 W = pose_from_xyz_rpy_deg(0, 0, 0, -90, 0, 0);  // z -> y
  const Points3 target = transform_points(W, p.target);
  const Points3 source = transform_points(W, p.source);
  const Isometry3 T_true = W * p.T_target_source * W.inverse();
  GlobalInitOptions o;
  o.up = Vec3::UnitY();
  const GlobalInitResult r = global_align(source, PreparedTarget(target), o);
  const TransformError e = transform_error(r.T_target_source, T_true);
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.02);
  // With the wrong up axis (z), the yaw search cannot express the rotation: no good inlier set.
  const GlobalInitResult wrong = global_align(source, PreparedTarget(target));
  EXPECT_LT(wrong.inlier_fraction, r.inlier_fraction);
}

TEST(GlobalInit, DeterministicForAnyThreadCount) {
  const Pair p = make_pair(-60.0, 0.7, 2.2, 91);
  const PreparedTarget target(p.target);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const GlobalInitResult one = global_align(p.source, target);
  omp_set_num_threads(2);
  const GlobalInitResult two = global_align(p.source, target);
  omp_set_num_threads(saved);
  EXPECT_TRUE(one.T_target_source.matrix() == two.T_target_source.matrix());
  EXPECT_EQ(one.inlier_fraction, two.inlier_fraction);
  ASSERT_EQ(one.hypotheses.size(), two.hypotheses.size());
  for (std::size_t i = 0; i < one.hypotheses.size(); ++i) {
    EXPECT_EQ(one.hypotheses[i].votes, two.hypotheses[i].votes);
    EXPECT_EQ(one.hypotheses[i].yaw_deg, two.hypotheses[i].yaw_deg);
  }
}

TEST(GlobalInit, InvalidOptionsAndInputsAreNamed) {
  std::string why;
  GlobalInitOptions o;
  o.yaw_step_deg = 0.0;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("yaw_step_deg"), std::string::npos);
  o = GlobalInitOptions();
  o.up = Vec3::Zero();
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("up"), std::string::npos);
  o = GlobalInitOptions();
  o.refine_schedule_m = {0.1, -1.0};
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("refine_schedule_m"), std::string::npos);
  o = GlobalInitOptions();
  o.inlier_distance_m = std::nan("");
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("inlier_distance_m"), std::string::npos);

  const PreparedTarget target(test::room_points(100, 5));
  EXPECT_THROW(global_align({Vec3::Zero(), Vec3::UnitX()}, target), InvalidArgument);
  Points3 bad = test::room_points(10, 6);
  bad[3].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(global_align(bad, target), InvalidArgument);
  o.yaw_step_deg = 200;
  EXPECT_THROW(global_align(test::room_points(10, 6), target, o), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
