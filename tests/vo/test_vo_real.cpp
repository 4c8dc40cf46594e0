// The map builder on the 9 real TUM fr1/desk RGB-D frames in ../shared/data/tum_fr1_desk,
// checked against groundtruth.txt; the map is written, reloaded and aligned onto itself.
#include <cstdio>
#include <filesystem>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "lmalign/core/geometry.hpp"
#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/vo/map_builder.hpp"
#include "support/align_preset.hpp"
#include "support/data_path.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

TEST(VoReal, NineFramesOfFr1DeskAgainstGroundTruth) {
  const std::string folder = test::data_file("tum_fr1_desk");
  LMALIGN_REQUIRE_FILE(folder + "/rgb.txt");
  LMALIGN_REQUIRE_FILE(folder + "/groundtruth.txt");
  const vo::TumSequence seq = vo::load_tum_sequence(folder);
  ASSERT_EQ(seq.frames.size(), 573u);  // associate.txt lists 573 pairs
  ASSERT_TRUE(seq.ground_truth.has_value());
  vo::MapBuilderOptions o = {};
  o.camera = vo::tum_camera_preset("fr1");
  o.init_from_ground_truth = true;
  o.max_frames = 9;  // only the first 9 images are present
  const auto r = vo::build_map(seq, o);
  EXPECT_EQ(r.stats.frames, 9u);
  EXPECT_EQ(r.stats.frames_lost, 0u);
  EXPECT_GE(r.stats.keyframes, 2u);

  AteOptions raw;
  raw.align = false;  // the map is in the motion-capture frame
  const AteResult frames = absolute_trajectory_error(r.frame_trajectory, *seq.ground_truth, raw);
  const AteResult aligned = absolute_trajectory_error(r.frame_trajectory, *seq.ground_truth);
  std::printf(
      "fr1/desk 9 frames: %zu keyframes, %zu landmarks (%zu with n>=2); frame ATE "
      "unaligned rmse %.4f max %.4f m %.2f deg; aligned rmse %.4f m\n",
      r.stats.keyframes, r.stats.landmarks, r.stats.landmarks_two_plus, frames.translation_m.rmse,
      frames.translation_m.max, frames.rotation_deg.max, aligned.translation_m.rmse);
  EXPECT_EQ(frames.pairs.size(), 9u);
  EXPECT_LT(frames.translation_errors_m.front(), 1e-9);  // first frame = ground truth
  EXPECT_LT(frames.translation_m.rmse, 0.02);
  EXPECT_LT(aligned.translation_m.rmse, 0.02);
  EXPECT_LT(frames.rotation_deg.max, 3.0);

  // Written, reloaded (the paper's loader: n >= 2), and aligned onto itself from a displacement.
  const fs::path p =
      fs::temp_directory_path() / ("lmalign_vo_real_" + std::to_string(::getpid()) + ".txt");
  write_map(p.string(), r.map);
  const Map map = read_map(p.string());
  fs::remove(p);
  EXPECT_EQ(map.frames.size(), r.stats.keyframes);
  EXPECT_EQ(map.landmarks.size(), r.stats.landmarks_two_plus);
  ASSERT_GT(map.landmarks.size(), 100u);
  const Isometry3 D = pose_from_xyz_rpy_deg(0.05, -0.03, 0.02, 2.0, -1.0, 3.0);
  const Map displaced = transform_map(map, D);
  const RegistrationResult result =
      test::align_with("base", SourceLandmarks::from_map(displaced), PreparedTarget(map))
          .registration;
  const TransformError err = transform_error(result.T_target_source * D, Isometry3::Identity());
  EXPECT_LT(err.rotation_deg, 0.01);
  EXPECT_LT(err.translation_m, 1e-4);
}

}  // namespace
}  // namespace lmalign
