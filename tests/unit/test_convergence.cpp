#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/convergence.hpp"

namespace lmalign {
namespace {

Correspondences pairs_with_mse(double mse) { return {{0, 0, mse * 0.5}, {1, 1, mse * 1.5}}; }

const Isometry3 kSmallStep = pose_from_xyz_rpy_deg(1e-3, 0, 0, 0, 0, 0.01);

TEST(ConvergenceCriteria, MaxIterationsFirst) {
  ConvergenceOptions o;
  o.max_iterations = 3;
  ConvergenceCriteria c(o);
  EXPECT_EQ(c.check(1, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kNotTerminated);
  EXPECT_EQ(c.check(2, kSmallStep, pairs_with_mse(2.0)), TerminationReason::kNotTerminated);
  // Iteration 3 stops on the budget even though the MSE did not change and the step is identity.
  EXPECT_EQ(c.check(3, Isometry3::Identity(), pairs_with_mse(2.0)),
            TerminationReason::kMaxIterations);
}

TEST(ConvergenceCriteria, TransformFiresOnlyForExactIdentityWithIcpDefaults) {
  ConvergenceCriteria c{ConvergenceOptions{}};
  EXPECT_EQ(c.check(1, pose_from_xyz_rpy_deg(1e-12, 0, 0, 0, 0, 0), pairs_with_mse(1.0)),
            TerminationReason::kNotTerminated);
  EXPECT_EQ(c.check(2, Isometry3::Identity(), pairs_with_mse(0.5)), TerminationReason::kTransform);
}

TEST(ConvergenceCriteria, AbsoluteMseNeedsTwoIterations) {
  ConvergenceCriteria c{ConvergenceOptions{}};
  // First check: previous MSE is DBL_MAX, never "similar".
  EXPECT_EQ(c.check(1, kSmallStep, pairs_with_mse(0.25)), TerminationReason::kNotTerminated);
  EXPECT_DOUBLE_EQ(c.last_mse_m2(), 0.25);
  EXPECT_EQ(c.check(2, kSmallStep, pairs_with_mse(0.25 + 1e-9)), TerminationReason::kNotTerminated);
  EXPECT_EQ(c.check(3, kSmallStep, pairs_with_mse(0.25 + 1e-9 + 1e-13)),
            TerminationReason::kAbsoluteMse);
}

TEST(ConvergenceCriteria, RelativeMseDisabledByDefaultEnabledOnRequest) {
  ConvergenceCriteria off{ConvergenceOptions{}};
  EXPECT_EQ(off.check(1, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kNotTerminated);
  EXPECT_EQ(off.check(2, kSmallStep, pairs_with_mse(1.0 + 1e-9)),
            TerminationReason::kNotTerminated);
  ConvergenceOptions o;
  o.euclidean_fitness_epsilon = 1e-6;
  ConvergenceCriteria on(o);
  EXPECT_EQ(on.check(1, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kNotTerminated);
  EXPECT_EQ(on.check(2, kSmallStep, pairs_with_mse(1.0 + 1e-9)), TerminationReason::kRelativeMse);
}

TEST(ConvergenceCriteria, SimilarIterationsMustRepeat) {
  ConvergenceOptions o;
  o.max_iterations_similar_transforms = 2;
  ConvergenceCriteria c(o);
  EXPECT_EQ(c.check(1, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kNotTerminated);
  EXPECT_EQ(c.check(2, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kNotTerminated);  // 1
  EXPECT_EQ(c.check(3, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kNotTerminated);  // 2
  EXPECT_EQ(c.check(4, kSmallStep, pairs_with_mse(1.0)), TerminationReason::kAbsoluteMse);
  // A dissimilar iteration resets the count.
  ConvergenceCriteria d(o);
  d.check(1, kSmallStep, pairs_with_mse(1.0));
  d.check(2, kSmallStep, pairs_with_mse(1.0));
  EXPECT_EQ(d.check(3, kSmallStep, pairs_with_mse(2.0)), TerminationReason::kNotTerminated);
  EXPECT_EQ(d.check(4, kSmallStep, pairs_with_mse(2.0)), TerminationReason::kNotTerminated);
}

TEST(ConvergenceOptions, ValidationNamesTheField) {
  std::string why;
  ConvergenceOptions o;
  o.max_iterations = 0;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("max_iterations"), std::string::npos);
  o = ConvergenceOptions{};
  o.min_correspondences = 2;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("min_correspondences"), std::string::npos);
  o = ConvergenceOptions{};
  o.transformation_epsilon_m2 = -1;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("transformation_epsilon_m2"), std::string::npos);
  EXPECT_THROW(ConvergenceCriteria{o}, InvalidArgument);
  EXPECT_TRUE(ConvergenceOptions{}.is_valid());
}

TEST(TerminationReason, Names) {
  EXPECT_EQ(to_string(TerminationReason::kAbsoluteMse), "absolute_mse");
  EXPECT_EQ(to_string(TerminationReason::kNoCorrespondences), "no_correspondences");
}

}  // namespace
}  // namespace lmalign
