// Trajectory I/O, association, ATE and RPE (include/lmalign/eval/trajectory.hpp) on synthetic
// trajectories with known answers.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/eval/trajectory.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

Trajectory make_circle(std::size_t n, double t0, double dt) {
  Trajectory t;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 0.05 * static_cast<double>(i);
    StampedPose p;
    p.timestamp_s = t0 + dt * static_cast<double>(i);
    p.T_world_camera =
        pose_from_xyz_rpy_deg(std::cos(a), std::sin(a), 0.1 * a, 5.0 * a, 2.0, a * 57.0);
    t.push_back(p);
  }
  return t;
}

class EvalFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("lmalign_eval_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const std::string p = (dir_ / name).string();
    std::ofstream(p) << text;
    return p;
  }
  fs::path dir_;
};

TEST_F(EvalFiles, TumRoundTripIsExactAndSorted) {
  Trajectory t = make_circle(20, 100.0, 0.033);
  std::swap(t[3], t[7]);
  const std::string p = (dir_ / "t.txt").string();
  write_tum_trajectory(p, t);
  const Trajectory r = read_tum_trajectory(p);
  ASSERT_EQ(r.size(), t.size());
  for (std::size_t i = 1; i < r.size(); ++i) EXPECT_LT(r[i - 1].timestamp_s, r[i].timestamp_s);
  const Trajectory sorted = make_circle(20, 100.0, 0.033);
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_EQ(r[i].timestamp_s, sorted[i].timestamp_s);
    EXPECT_TRUE(r[i].T_world_camera.isApprox(sorted[i].T_world_camera, 1e-12));
  }
}

TEST_F(EvalFiles, TumQuaternionOrderIsXyzw) {
  // 90 degrees about z: qx qy qz qw = 0 0 0.7071 0.7071.
  const auto p = write("q.txt", "# comment\n1.0 1 2 3 0 0 0.7071067811865476 0.7071067811865476\n");
  const Trajectory t = read_tum_trajectory(p);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_TRUE((t[0].T_world_camera.linear() * Vec3::UnitX()).isApprox(Vec3::UnitY(), 1e-12));
  EXPECT_TRUE(t[0].T_world_camera.translation().isApprox(Vec3(1, 2, 3)));
}

TEST_F(EvalFiles, BadTumLinesNameFileAndLine) {
  auto expect_error = [&](const std::string& text, std::size_t line, const std::string& part) {
    const auto p = write("bad.txt", text);
    try {
      read_tum_trajectory(p);
      FAIL() << "no error for: " << text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.file(), p);
      EXPECT_EQ(e.line(), line);
      EXPECT_NE(e.detail().find(part), std::string::npos) << e.what();
    }
  };
  expect_error("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", 2, "7 fields, expected 8");
  expect_error("# c\n\n1 0 0 abc 0 0 0 1\n", 3, "'tz' is not a number");
  expect_error("1 0 0 0 0 0 0 nan\n", 1, "not finite");
  expect_error("1 0 0 0 0 0 0 2\n", 1, "quaternion norm");
  expect_error("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 2, "duplicate timestamp");
  EXPECT_THROW(read_tum_trajectory((dir_ / "missing.txt").string()), IoError);
}

TEST_F(EvalFiles, FrameTimesAndMapTrajectory) {
  const auto p = write("ft.txt", "0 10.5\n2 10.0\n");
  const auto times = read_frame_times(p);
  ASSERT_EQ(times.size(), 2u);
  Map map;
  for (Id id : {0, 2}) {
    Frame f;
    f.id = id;
    f.p_world_camera = Vec3(static_cast<double>(id), 0, 0);
    map.frames.push_back(f);
  }
  const Trajectory t = trajectory_from_map(map, times);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].timestamp_s, 10.0);
  EXPECT_EQ(t[0].T_world_camera.translation().x(), 2.0);
  Frame extra;
  extra.id = 7;
  map.frames.push_back(extra);
  EXPECT_THROW(trajectory_from_map(map, times), InvalidArgument);
  const auto bad = write("bad.txt", "0 1\n0 2\n");
  EXPECT_THROW(read_frame_times(bad), ParseError);
  const auto bad2 = write("bad2.txt", "0 1\n-1 2\n");
  EXPECT_THROW(read_frame_times(bad2), ParseError);
}

TEST(Associate, NearestWithinMaxDifferenceEachUsedOnce) {
  Trajectory est, gt;
  for (double t : {1.0, 1.05, 2.0}) est.push_back({t, Isometry3::Identity()});
  for (double t : {1.01, 1.03, 1.5, 2.05}) gt.push_back({t, Isometry3::Identity()});
  const auto pairs = associate_trajectories(est, gt, 0.02);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].estimate_index, 0u);
  EXPECT_EQ(pairs[0].ground_truth_index, 0u);
  EXPECT_EQ(pairs[1].estimate_index, 1u);
  EXPECT_EQ(pairs[1].ground_truth_index, 1u);
  // An offset moves the ground truth: 2.05 - 0.05 matches 2.0.
  EXPECT_EQ(associate_trajectories(est, gt, 0.005, -0.05).size(), 1u);
}

TEST(Ate, RigidlyMovedTrajectoryHasZeroErrorAfterAlignment) {
  const Trajectory gt = make_circle(50, 0.0, 0.1);
  const Isometry3 T = pose_from_xyz_rpy_deg(0.3, -1.0, 2.0, 10.0, -20.0, 75.0);
  Trajectory est = gt;
  for (auto& p : est) {
    p.T_world_camera = T * p.T_world_camera;
    p.timestamp_s += 0.004;
  }
  const AteResult r = absolute_trajectory_error(est, gt);
  EXPECT_EQ(r.pairs.size(), 50u);
  EXPECT_LT(r.translation_m.rmse, 1e-12);
  EXPECT_LT(r.rotation_deg.max, 1e-6);
  EXPECT_TRUE(r.T_gt_est.isApprox(T.inverse(), 1e-9));
  AteOptions no_align;
  no_align.align = false;
  EXPECT_GT(absolute_trajectory_error(est, gt, no_align).translation_m.rmse, 1.0);
}

TEST(Ate, RmseMatchesKnownNoise) {
  // Positions perturbed by +-d along z alternately: the best rigid fit is (nearly) the identity
  // and the RMSE is d.
  const Trajectory gt = make_circle(200, 0.0, 0.1);
  Trajectory est = gt;
  const double d = 0.01;
  for (std::size_t i = 0; i < est.size(); ++i) {
    est[i].T_world_camera.translation().z() += (i % 2 == 0 ? d : -d);
  }
  const AteResult r = absolute_trajectory_error(est, gt);
  EXPECT_NEAR(r.translation_m.rmse, d, 2e-4);
  EXPECT_NEAR(r.translation_m.mean, d, 3e-4);
}

TEST(Ate, TooFewPairsThrows) {
  const Trajectory gt = make_circle(10, 0.0, 0.1);
  const Trajectory est = make_circle(10, 100.0, 0.1);
  EXPECT_THROW(absolute_trajectory_error(est, gt), InvalidArgument);
}

TEST(Rpe, ConstantDriftPerSecond) {
  // The estimate gains 2 cm along the camera's own x axis per second (0.1 s steps): each 1 s
  // relative motion is off by exactly 2 cm; rotations are exact.
  const Trajectory gt = make_circle(60, 0.0, 0.1);
  Trajectory est;
  Isometry3 P = gt[0].T_world_camera;
  est.push_back(gt[0]);
  for (std::size_t i = 1; i < gt.size(); ++i) {
    Isometry3 step = gt[i - 1].T_world_camera.inverse() * gt[i].T_world_camera;
    Isometry3 bias = Isometry3::Identity();
    bias.translation() = Vec3(0.002, 0, 0);
    P = P * bias * step;  // bias applied before the step, in the previous camera's frame
    est.push_back({gt[i].timestamp_s, P});
  }
  RpeOptions o;
  o.delta_s = 1.0;
  o.delta_tolerance_s = 0.01;  // exactly the pairs 1 s apart
  const RpeResult r = relative_pose_error(est, gt, o);
  EXPECT_EQ(r.translation_m.count, 50u);
  EXPECT_LT(r.rotation_deg.max, 1e-9);
  // 10 steps of 2 mm, each expressed in a different (rotating) frame: at most 2 cm.
  EXPECT_GT(r.translation_m.mean, 0.01);
  EXPECT_LE(r.translation_m.max, 0.02 + 1e-9);
  // The exact trajectory has no error.
  EXPECT_LT(relative_pose_error(gt, gt, o).translation_m.max, 1e-12);
}

TEST(AlignRigid, RecoversTransformAndGuardsReflection) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  Points3 src;
  for (int i = 0; i < 30; ++i) src.emplace_back(n(rng), n(rng), n(rng));
  const Isometry3 T = pose_from_xyz_rpy_deg(1, 2, 3, 170, 40, -100);
  const Isometry3 est = align_rigid(src, transform_points(T, src));
  EXPECT_TRUE(est.isApprox(T, 1e-9));
  EXPECT_GT(est.linear().determinant(), 0.0);
  EXPECT_THROW(align_rigid(src, Points3{}), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
