// ATE and RPE of the paper authors' own odometry (map_fr1_desk.txt + frame_times.txt) against the
// TUM ground truth (method.md §6: median 7 cm, at most 27 cm and 13 degrees of drift).
#include <string>

#include <gtest/gtest.h>

#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/data_path.hpp"

namespace lmalign {
namespace {

TEST(EvalTrajectoryReal, AuthorsOdometryDriftsAsDocumented) {
  const std::string map_path = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  const std::string times_path = test::data_file("tum_fr1_desk/frame_times.txt");
  const std::string gt_path = test::data_file("tum_fr1_desk/groundtruth.txt");
  LMALIGN_REQUIRE_FILE(map_path);
  LMALIGN_REQUIRE_FILE(times_path);
  LMALIGN_REQUIRE_FILE(gt_path);
  MapReadOptions o;
  o.min_observations = 0;
  const Map map = read_map(map_path, o);
  const Trajectory est = trajectory_from_map(map, read_frame_times(times_path), times_path);
  const Trajectory gt = read_tum_trajectory(gt_path);
  ASSERT_EQ(est.size(), 240u);
  ASSERT_EQ(gt.size(), 2335u);

  // FRAME 0 is the ground-truth pose at its time: without alignment, the first pose matches.
  AteOptions raw;
  raw.align = false;
  const AteResult unaligned = absolute_trajectory_error(est, gt, raw);
  EXPECT_EQ(unaligned.pairs.size(), 240u);
  EXPECT_LT(unaligned.translation_errors_m.front(), 0.01);
  // The unaligned drift as documented: median ~7 cm, at most ~27 cm and ~13 degrees.
  EXPECT_GT(unaligned.translation_m.median, 0.04);
  EXPECT_LT(unaligned.translation_m.median, 0.10);
  EXPECT_GT(unaligned.translation_m.max, 0.20);
  EXPECT_LT(unaligned.translation_m.max, 0.32);
  EXPECT_GT(unaligned.rotation_deg.max, 10.0);
  EXPECT_LT(unaligned.rotation_deg.max, 16.0);

  // After the best rigid alignment the error can only shrink, but the drift is real.
  const AteResult ate = absolute_trajectory_error(est, gt);
  EXPECT_LE(ate.translation_m.rmse, unaligned.translation_m.rmse);
  EXPECT_GT(ate.translation_m.rmse, 0.03);
  EXPECT_LT(ate.translation_m.rmse, 0.15);

  const RpeResult rpe = relative_pose_error(est, gt);
  EXPECT_GT(rpe.translation_m.count, 150u);
  EXPECT_GT(rpe.translation_m.rmse, 0.01);
  EXPECT_LT(rpe.translation_m.rmse, 0.2);
  RecordProperty("ate_rmse_m", std::to_string(ate.translation_m.rmse));
  std::printf(
      "authors' odometry: ATE rmse %.4f m (unaligned median %.4f max %.4f m, %.2f deg), "
      "RPE(1 s) rmse %.4f m %.3f deg\n",
      ate.translation_m.rmse, unaligned.translation_m.median, unaligned.translation_m.max,
      unaligned.rotation_deg.max, rpe.translation_m.rmse, rpe.rotation_deg.rmse);
}

}  // namespace
}  // namespace lmalign
