// The map builder on a synthetic RGB-D sequence that this test renders itself (textured room,
// known trajectory, seeded image and depth noise): trajectory error, landmark accuracy, and
// consistency of the landmark covariances (NEES against chi-square bounds, 3 dof).
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <unordered_map>

#include <gtest/gtest.h>

#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/vo/map_builder.hpp"
#include "vo/synthetic_rgbd.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

// One rendering and one run shared by all checks (ctest runs each TEST in its own process, so
// the checks are sections of a single TEST rather than separate tests).
fs::path* dir_ = nullptr;
vo::TumSequence* sequence_ = nullptr;
vo::MapBuilderResult* result_ = nullptr;

void TracksEveryFrameWithSubCentimetreTrajectoryError() {
  const auto& r = *result_;
  EXPECT_EQ(r.stats.frames, 100u);
  EXPECT_EQ(r.stats.frames_lost, 0u);
  EXPECT_EQ(r.frame_trajectory.size(), 100u);
  EXPECT_GE(r.stats.keyframes, 5u);
  // In the ground-truth frame (first keyframe initialised from it): no alignment needed.
  AteOptions raw;
  raw.align = false;
  const AteResult frames =
      absolute_trajectory_error(r.frame_trajectory, *sequence_->ground_truth, raw);
  const AteResult keyframes =
      absolute_trajectory_error(r.keyframe_trajectory, *sequence_->ground_truth, raw);
  std::printf(
      "synthetic: %zu keyframes, frame ATE rmse %.4f m max %.4f m, keyframe ATE rmse "
      "%.4f m, rot max %.3f deg\n",
      r.stats.keyframes, frames.translation_m.rmse, frames.translation_m.max,
      keyframes.translation_m.rmse, frames.rotation_deg.max);
  EXPECT_EQ(frames.pairs.size(), 100u);
  EXPECT_LT(frames.translation_m.rmse, 0.01);
  EXPECT_LT(keyframes.translation_m.rmse, 0.01);
  EXPECT_LT(frames.translation_m.max, 0.01);  // every frame: "stays below 1 cm" (issue 6)
  EXPECT_LT(frames.rotation_deg.max, 0.5);
}

// Each landmark with >= 2 observations against the true surface point seen along the ray of its
// first observation (from the ground-truth pose of that keyframe).
struct LandmarkErrors {
  std::vector<double> error_m;
  std::vector<double> nees;
};

LandmarkErrors landmark_errors(const vo::MapBuilderResult& r) {
  std::unordered_map<Id, Isometry3> gt_pose;
  for (std::size_t k = 0; k < r.keyframe_trajectory.size(); ++k) {
    const double t = r.keyframe_trajectory[k].timestamp_s;
    const auto i = static_cast<std::size_t>(std::lround((t - 1000.0) * 30.0));
    gt_pose[static_cast<Id>(k)] = test::synthetic_pose(i);
  }
  LandmarkErrors out;
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  for (const auto& lm : r.map.landmarks) {
    if (lm.num_observations() < 2) continue;
    const auto& ob = lm.observations.front();
    const Vec3 truth = test::synthetic_surface_point(gt_pose.at(ob.frame_id), k, ob.u_px, ob.v_px);
    const Vec3 e = lm.p_world - truth;
    out.error_m.push_back(e.norm());
    out.nees.push_back(e.dot(lm.cov_world_m2.ldlt().solve(e)));
  }
  return out;
}

void LandmarksWithinFewCentimetres() {
  const auto e = landmark_errors(*result_);
  ASSERT_GT(e.error_m.size(), 200u);
  const ErrorStats s = error_stats(e.error_m);
  std::printf("synthetic: %zu landmarks (n>=2), error median %.4f m, rmse %.4f m, max %.4f m\n",
              s.count, s.median, s.rmse, s.max);
  EXPECT_LT(s.median, 0.01);
  EXPECT_LT(s.rmse, 0.03);
  std::size_t far = 0;
  for (double x : e.error_m) far += x > 0.05 ? 1 : 0;
  EXPECT_LT(static_cast<double>(far), 0.02 * static_cast<double>(e.error_m.size()));
}

void CovariancesAreConsistentWithErrors() {
  const auto e = landmark_errors(*result_);
  ASSERT_GT(e.nees.size(), 200u);
  // Mean NEES over N landmarks: N * mean ~ chi2(3N) if the covariances are right. Landmark
  // errors are correlated through the shared poses, so the test uses the 99.9% two-sided bounds
  // of the mean of 3-dof chi-square variables over a conservative effective sample of 100.
  // chi2(300) quantiles 0.0005 / 0.9995: 228.4 / 380.8 -> mean NEES in [2.28, 3.81].
  double mean = 0.0;
  for (double x : e.nees) mean += x;
  mean /= static_cast<double>(e.nees.size());
  std::size_t inside = 0;
  for (double x : e.nees) inside += x <= 7.815 ? 1 : 0;  // chi2(3) 95%
  const double fraction = static_cast<double>(inside) / static_cast<double>(e.nees.size());
  std::printf(
      "synthetic: mean NEES %.3f over %zu landmarks (3 expected), %.1f%% within the "
      "chi2(3) 95%% bound\n",
      mean, e.nees.size(), 100.0 * fraction);
  EXPECT_GT(mean, 2.28);
  EXPECT_LT(mean, 3.81);
  EXPECT_GT(fraction, 0.85);
}

void MapRoundTripsAndObservationsReprojectIntoTheirKeyframes() {
  const auto& map = result_->map;
  const fs::path p = *dir_ / "map.txt";
  write_map(p.string(), map);
  MapReadOptions all;
  all.min_observations = 0;
  const Map back = read_map(p.string(), all);
  ASSERT_EQ(back.landmarks.size(), map.landmarks.size());
  ASSERT_EQ(back.frames.size(), result_->stats.keyframes);
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  std::vector<double> reproj;
  for (const auto& lm : back.landmarks) {
    for (const auto& ob : lm.observations) {
      const Vec3 pc = back.find_frame(ob.frame_id)->T_world_camera().inverse() * lm.p_world;
      reproj.push_back((k.project(pc) - Eigen::Vector2d(ob.u_px, ob.v_px)).norm());
    }
  }
  EXPECT_LT(error_stats(reproj).median, 1.0);
}

void DeterministicForSameInput() {
  vo::MapBuilderOptions o;
  o.init_from_ground_truth = true;
  o.max_frames = 10;
  const auto a = vo::build_map(*sequence_, o);
  const auto b = vo::build_map(*sequence_, o);
  ASSERT_EQ(a.map.landmarks.size(), b.map.landmarks.size());
  for (std::size_t i = 0; i < a.map.landmarks.size(); ++i) {
    ASSERT_EQ(a.map.landmarks[i].p_world, b.map.landmarks[i].p_world);
    ASSERT_EQ(a.map.landmarks[i].cov_world_m2, b.map.landmarks[i].cov_world_m2);
  }
}

TEST(VoSynthetic, HundredFramesOfATexturedRoom) {
  const fs::path dir =
      fs::temp_directory_path() / ("lmalign_vo_synth_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  test::render_synthetic_sequence(dir.string());
  vo::TumSequence sequence = vo::load_tum_sequence(dir.string());
  ASSERT_EQ(sequence.frames.size(), 100u);
  ASSERT_TRUE(sequence.ground_truth.has_value());
  vo::MapBuilderOptions o;
  o.init_from_ground_truth = true;
  vo::MapBuilderResult result = vo::build_map(sequence, o);
  fs::path dir_copy = dir;
  dir_ = &dir_copy;
  sequence_ = &sequence;
  result_ = &result;
  {
    SCOPED_TRACE("TracksEveryFrameWithSubCentimetreTrajectoryError");
    TracksEveryFrameWithSubCentimetreTrajectoryError();
  }
  {
    SCOPED_TRACE("LandmarksWithinFewCentimetres");
    LandmarksWithinFewCentimetres();
  }
  {
    SCOPED_TRACE("CovariancesAreConsistentWithErrors");
    CovariancesAreConsistentWithErrors();
  }
  {
    SCOPED_TRACE("MapRoundTripsAndObservationsReprojectIntoTheirKeyframes");
    MapRoundTripsAndObservationsReprojectIntoTheirKeyframes();
  }
  {
    SCOPED_TRACE("DeterministicForSameInput");
    DeterministicForSameInput();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lmalign
