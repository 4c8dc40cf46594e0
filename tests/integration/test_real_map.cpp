// Loading the real TUM fr1/desk landmark maps (method.md §1, data/tum_fr1_desk/SOURCE.md).
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "lmalign/map/map.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/data_path.hpp"
#include "support/map_compare.hpp"

namespace lmalign {
namespace {

const std::string kRealMap = "tum_fr1_desk/map_fr1_desk.txt";

MapReadOptions keep_all() {
  MapReadOptions options;
  options.min_observations = 0;
  return options;
}

TEST(RealMap, CountsWithDefaultAndNoFilter) {
  const std::string path = test::data_file(kRealMap);
  LMALIGN_REQUIRE_FILE(path);
  const Map map = read_map(path);
  EXPECT_EQ(map.frames.size(), 240u);
  EXPECT_EQ(map.landmarks.size(), 6081u);
  for (const Landmark& landmark : map.landmarks) ASSERT_GE(landmark.num_observations(), 2u);
  const Map all = read_map(path, keep_all());
  EXPECT_EQ(all.frames.size(), 240u);
  EXPECT_EQ(all.landmarks.size(), 22338u);
  EXPECT_NO_THROW(all.validate());
}

TEST(RealMap, EveryCovarianceIsSymmetricPositiveDefinite) {
  const std::string path = test::data_file(kRealMap);
  LMALIGN_REQUIRE_FILE(path);
  const Map map = read_map(path, keep_all());
  for (const Landmark& landmark : map.landmarks) {
    const Mat3& cov = landmark.cov_world_m2;
    ASSERT_LE((cov - cov.transpose()).cwiseAbs().maxCoeff(), 1e-12 * cov.cwiseAbs().maxCoeff())
        << "LANDMARK " << landmark.id;
    const Eigen::SelfAdjointEigenSolver<Mat3> solver(cov, Eigen::EigenvaluesOnly);
    ASSERT_GT(solver.eigenvalues()(0), 0.0) << "LANDMARK " << landmark.id;
  }
}

TEST(RealMap, FrameZeroEqualsTumGroundTruth) {
  const std::string path = test::data_file(kRealMap);
  const std::string gt_path = test::data_file("tum_fr1_desk/groundtruth.txt");
  LMALIGN_REQUIRE_FILE(path);
  LMALIGN_REQUIRE_FILE(gt_path);
  const Map map = read_map(path);
  const Frame* frame = map.find_frame(0);
  ASSERT_NE(frame, nullptr);

  // groundtruth.txt: timestamp tx ty tz qx qy qz qw (TUM order, scalar last).
  std::ifstream gt(gt_path);
  std::string line;
  bool found = false;
  Vec3 t_gt;
  Quat q_gt;
  while (std::getline(gt, line)) {
    if (line.rfind("1305031453.3695 ", 0) != 0) continue;
    std::istringstream fields(line);
    double stamp = 0, qx = 0, qy = 0, qz = 0, qw = 0;
    fields >> stamp >> t_gt.x() >> t_gt.y() >> t_gt.z() >> qx >> qy >> qz >> qw;
    ASSERT_TRUE(fields) << line;
    q_gt = Quat(qw, qx, qy, qz);
    found = true;
    break;
  }
  ASSERT_TRUE(found) << "no ground-truth line at t=1305031453.3695";
  EXPECT_LT((frame->p_world_camera - t_gt).norm(), 1e-4);
  // The map's quaternion is scalar first; q and -q are the same rotation.
  const double angle = frame->q_world_camera.normalized().angularDistance(q_gt.normalized());
  EXPECT_LT(angle, 1e-3) << "rotation differs by " << angle << " rad";
}

TEST(RealMap, GroundTruthPairLoads) {
  const std::string a_path = test::data_file("tum_fr1_desk/ground_truth_pair/desk_gt_a.txt");
  const std::string b_path = test::data_file("tum_fr1_desk/ground_truth_pair/desk_gt_b.txt");
  LMALIGN_REQUIRE_FILE(a_path);
  LMALIGN_REQUIRE_FILE(b_path);
  const Map a = read_map(a_path);
  const Map b = read_map(b_path);
  EXPECT_EQ(a.landmarks.size(), 3050u);
  EXPECT_EQ(b.landmarks.size(), 3027u);
  EXPECT_EQ(a.frames.size(), 120u);
  EXPECT_EQ(b.frames.size(), 120u);
  // Frames 0-119 and 120-239.
  EXPECT_NE(a.find_frame(0), nullptr);
  EXPECT_EQ(a.find_frame(120), nullptr);
  EXPECT_NE(b.find_frame(239), nullptr);
  EXPECT_EQ(b.find_frame(119), nullptr);
  // Every landmark of the pair already has n >= 2, so the filter drops nothing.
  EXPECT_EQ(read_map(a_path, keep_all()).landmarks.size(), 3050u);
}

TEST(RealMap, ReadWriteReadIsExact) {
  const std::string path = test::data_file(kRealMap);
  LMALIGN_REQUIRE_FILE(path);
  const Map first = read_map(path, keep_all());

  const auto dir = std::filesystem::temp_directory_path() /
                   ("lmalign_test_real_map_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string out_path = (dir / "map.txt").string();
  write_map(out_path, first);
  const Map second = read_map(out_path, keep_all());
  std::filesystem::remove_all(dir);

  EXPECT_TRUE(test::maps_identical(first, second));
}

}  // namespace
}  // namespace lmalign
