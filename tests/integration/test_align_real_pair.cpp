// End-to-end on the real TUM fr1/desk mini-map pair whose true transform is the identity
// (desk_gt_a onto desk_gt_b; method.md §6). Starts and strategies asserted here are the ones
// measured to reach the right basin (docs/results-core.md lists the full measurement).
#include <omp.h>

#include <gtest/gtest.h>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/registration.hpp"
#include "support/align_preset.hpp"
#include "support/real_pair.hpp"

namespace lmalign {
namespace {

struct Case {
  const char* name;
  double x, y, z, roll, pitch, yaw;
};

class RealPair : public test::RealPairTest {
 protected:
  // Error of the recovered map-to-map transform (T_est * D) against the identity.
  static TransformError run(WeightKind s, const Case& c, RegistrationResult* out = nullptr) {
    const Isometry3 D = pose_from_xyz_rpy_deg(c.x, c.y, c.z, c.roll, c.pitch, c.yaw);
    test::Ask k5;
    k5.k = 5;
    const RegistrationResult r =
        test::align_with(test::paper_preset(s), transform_points(D, source_->positions()), *target_,
                         k5)
            .registration;
    if (out != nullptr) *out = r;
    return transform_error(r.T_target_source * D, Isometry3::Identity());
  }
};

constexpr Case kTable1{"table1", 0, 1, 0.4, 10, 0, 22.5};

TEST_F(RealPair, Table1DisplacementLandsInTheRightBasinWithTheMeasuredBias) {
  // method.md §6: a numpy ICP at the paper's settings ends 4.6 deg / 4.7 cm (base) and
  // 2.5 deg / 4.7 cm (observations) from the truth at this start.
  RegistrationResult r;
  TransformError e = run(WeightKind::kUniform, kTable1, &r);
  EXPECT_NEAR(e.rotation_deg, 4.6, 0.3);
  EXPECT_NEAR(e.translation_m, 0.047, 0.01);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.termination, TerminationReason::kAbsoluteMse);
  EXPECT_LT(r.final_score_m2, 0.1 * r.initial_score_m2);

  e = run(WeightKind::kObservations, kTable1);
  EXPECT_NEAR(e.rotation_deg, 2.5, 0.3);
  EXPECT_NEAR(e.translation_m, 0.047, 0.01);

  e = run(WeightKind::kCovariance, kTable1);
  EXPECT_LT(e.rotation_deg, 5.0);
  EXPECT_LT(e.translation_m, 0.10);
}

TEST_F(RealPair, BaseAndObservationsConvergeFromNearbyStarts) {
  for (const Case& c :
       {Case{"truth", 0, 0, 0, 0, 0, 0}, Case{"yaw10", 0, 0, 0, 0, 0, 10},
        Case{"yaw20", 0, 0, 0, 0, 0, 20}, Case{"+x+y0.25", 0.25, 0.25, 0, 0, 0, 0},
        Case{"+x-y0.5", 0.5, -0.5, 0, 0, 0, 0}, Case{"-x+y0.5yaw10", -0.5, 0.5, 0, 0, 0, 10}}) {
    for (WeightKind s : {WeightKind::kUniform, WeightKind::kObservations}) {
      const TransformError e = run(s, c);
      EXPECT_LT(e.rotation_deg, 5.0) << c.name << " " << to_string(s);
      EXPECT_LT(e.translation_m, 0.10) << c.name << " " << to_string(s);
      // The paper's objective is biased on this partial-overlap pair: never closer than ~2 deg.
      EXPECT_GT(e.rotation_deg, 1.5) << c.name << " " << to_string(s);
    }
  }
}

TEST_F(RealPair, Yaw30IsOutsideTheBasinOfBaseIcp) {
  // method.md §6 measured "yaw 30: wrong basin" for base and observations; we reproduce it.
  const TransformError e = run(WeightKind::kUniform, Case{"yaw30", 0, 0, 0, 0, 0, 30});
  EXPECT_GT(e.rotation_deg, 20.0);
}

TEST_F(RealPair, DeterministicAcrossThreadCounts) {
  const int saved = omp_get_max_threads();
  RegistrationResult one, two;
  omp_set_num_threads(1);
  run(WeightKind::kCovariance, kTable1, &one);
  omp_set_num_threads(2);
  run(WeightKind::kCovariance, kTable1, &two);
  omp_set_num_threads(saved);
  EXPECT_EQ(one.iterations, two.iterations);
  EXPECT_TRUE(one.T_target_source.matrix() == two.T_target_source.matrix());
  EXPECT_EQ(one.final_score_m2, two.final_score_m2);
}

}  // namespace
}  // namespace lmalign
