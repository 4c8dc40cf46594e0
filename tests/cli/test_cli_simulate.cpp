// `lmalign simulate`: the pair and its truth written as readable files, the same bytes for the
// same seed, the true transform relating the maps, and one-line errors naming the option.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "lmalign/core/geometry.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

using test::CliTest;
using test::read_text;
using test::shell_quote;

using CliSimulate = CliTest;

TEST_F(CliSimulate, RoadPairIsWrittenReadableAndReproducible) {
  const std::string a = path("a"), b = path("b");
  const std::string args =
      "simulate --scene road --seed 5 --overlap 0.25 --landmarks 400 "
      "--transform 1,2,3,0,0,30 -o ";
  const test::CliRun r = run(args + shell_quote(a));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("400 landmarks"), std::string::npos) << r.out;
  ASSERT_EQ(run(args + shell_quote(b)).exit_code, 0);
  for (const char* f : {"source.txt", "target.txt", "T_target_source.txt"}) {
    EXPECT_EQ(read_text(a + "/" + f), read_text(b + "/" + f)) << f;
  }
  const Map source = read_map(a + "/source.txt");
  const Map target = read_map(a + "/target.txt");
  EXPECT_EQ(source.landmarks.size(), 400u);
  EXPECT_EQ(target.landmarks.size(), 400u);
  const Isometry3 T = read_transform(a + "/T_target_source.txt");
  EXPECT_TRUE(T.isApprox(pose_from_xyz_rpy_deg(1, 2, 3, 0, 0, 30), 1e-12));
  // The source's keyframes, moved by the truth, drive the same road (x about 1.75 m, y = 0).
  for (const Frame& f : source.frames) {
    const Vec3 p = T * f.p_world_camera;
    EXPECT_NEAR(p.x(), 1.75, 0.31);
    EXPECT_NEAR(p.y(), 0.0, 1e-9);
  }
  // No temporary file is left beside the outputs.
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(a)) {
    (void)e;
    ++files;
  }
  EXPECT_EQ(files, 3u);
}

TEST_F(CliSimulate, StreetPairIsWrittenReadableAndReproducible) {
  const std::string args =
      "simulate --scene street --seed 3 --overlap 0.5 --frames 20 --landmarks 500 "
      "--transform 1,2,3,0,0,30 -o ";
  const test::CliRun r = run(args + shell_quote(path("a")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(run(args + shell_quote(path("b"))).exit_code, 0);
  for (const char* f : {"source.txt", "target.txt", "T_target_source.txt"}) {
    EXPECT_EQ(read_text(path("a") + "/" + f), read_text(path("b") + "/" + f)) << f;
  }
  const Map source = read_map(path("a") + "/source.txt");
  const Map target = read_map(path("a") + "/target.txt");
  EXPECT_EQ(source.landmarks.size(), 500u);
  ASSERT_EQ(target.frames.size(), 20u);
  const Isometry3 T = read_transform(path("a") + "/T_target_source.txt");
  EXPECT_TRUE(T.isApprox(pose_from_xyz_rpy_deg(1, 2, 3, 0, 0, 30), 1e-12));
  // Half of the keyframes are shared: the source's last 10 are the target's first 10.
  for (std::size_t f = 0; f < 10; ++f) {
    EXPECT_LT((T * source.frames[10 + f].p_world_camera - target.frames[f].p_world_camera).norm(),
              1e-9);
  }
}

// --windows N: a merge scene (maps, a manifest without priors, the truth) that lmalign merge reads.
TEST_F(CliSimulate, StreetWindowsForMerge) {
  const test::CliRun r = run("simulate --scene street --windows 3 --frames 20 --landmarks 400 -o " +
                             shell_quote(path("w")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("3 windows of 20 keyframes"), std::string::npos) << r.out;
  const std::string manifest = read_text(path("w") + "/manifest.yaml");
  EXPECT_EQ(manifest.find("T_world_map"), std::string::npos);  // no priors
  for (const char* name : {"w0", "w1", "w2"}) {
    EXPECT_NE(manifest.find(std::string("path: maps/") + name + ".txt"), std::string::npos);
    const Map m = read_map(path("w") + "/maps/" + name + ".txt");
    EXPECT_EQ(m.landmarks.size(), 400u);
    EXPECT_LT(m.frames.front().p_world_camera.norm(), 1e-9);  // its first keyframe's frame
  }
  EXPECT_NE(read_text(path("w") + "/ground_truth.yaml").find("w2: [["), std::string::npos);
}

TEST_F(CliSimulate, CorridorScene) {
  const test::CliRun r =
      run("simulate --scene corridor --landmarks 300 --overlap 0.9 -o " + shell_quote(path("c")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_map(path("c") + "/target.txt").landmarks.size(), 300u);
}

TEST_F(CliSimulate, BadOptionsAreOneLineErrorsNamingTheOption) {
  const auto error_of = [&](const std::string& args) {
    const test::CliRun r = run("simulate " + args + " -o " + shell_quote(path("x")));
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
    return r.err;
  };
  EXPECT_NE(error_of("--overlap 0.7").find("--overlap 0.7: must be in [0, 0.5]"),
            std::string::npos);
  EXPECT_NE(error_of("--scene corridor --overlap 0").find("--overlap 0: must be in (0, 1]"),
            std::string::npos);
  EXPECT_NE(error_of("--scene lake").find("--scene 'lake'"), std::string::npos);
  EXPECT_NE(error_of("--landmarks 3").find("num_landmarks"), std::string::npos);
  EXPECT_NE(error_of("--transform 1,2,3").find("--transform"), std::string::npos);
  EXPECT_NE(error_of("--scene street --overlap 0.8").find("--overlap 0.8: must be in [0, 0.75]"),
            std::string::npos);
  EXPECT_NE(error_of("--scene street --frames 1").find("--frames 1: must be in [2, 100000]"),
            std::string::npos);
  EXPECT_NE(error_of("--scene street --windows 1").find("--windows 1: must be in [2, 10000]"),
            std::string::npos);
  EXPECT_NE(error_of("--scene road --windows 3").find("only apply to --scene street"),
            std::string::npos);
  EXPECT_NE(error_of("--scene street --frames 2 --landmarks 900000").find("fewer than the 900000"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(path("x") + "/T_target_source.txt"));
}

}  // namespace
}  // namespace lmalign
