// `lmalign split`: runs the real binary (LMALIGN_CLI_PATH) on a small synthetic map.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/map/camera.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

using RunResult = test::CliRun;

std::string quote(const std::string& s) { return test::shell_quote(s); }

class CliSplit : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    input_ = (dir_ / "map.txt").string();
    write_map(input_, make_map());
  }

  // Ten frames along x looking along +z, 30 landmarks, each seen by frames i, i+1, i+2 (mod 10).
  static Map make_map() {
    const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
    Map map;
    for (Id id = 0; id < 10; ++id) {
      Frame f;
      f.id = id;
      f.p_world_camera = Vec3(0.1 * static_cast<double>(id), 0.0, 0.0);
      map.frames.push_back(f);
    }
    for (Id id = 0; id < 30; ++id) {
      Landmark l;
      l.id = 100 + id;
      l.p_world = Vec3(0.05 * static_cast<double>(id) - 0.3, 0.01 * static_cast<double>(id % 7),
                       2.0 + 0.03 * static_cast<double>(id));
      l.cov_world_m2 = Mat3::Identity() * 1e-4;
      for (Id j = 0; j < 3; ++j) {
        const Id frame_id = (id + j) % 10;
        const Eigen::Vector2d uv =
            k.project(l.p_world - map.frames[static_cast<std::size_t>(frame_id)].p_world_camera);
        l.observations.push_back({frame_id, uv.x(), uv.y()});
      }
      map.landmarks.push_back(l);
    }
    return map;
  }

  static std::size_t line_count(const std::string& text) {
    std::size_t n = 0;
    for (char c : text) n += (c == '\n');
    return n;
  }

  std::string input_;
};

TEST_F(CliSplit, GoodSplitWritesAReadableMiniMap) {
  const std::string output = (dir_ / "mini.txt").string();
  const RunResult r = run("split " + quote(input_) + " --frames 2-6 -o " + quote(output));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_NE(r.out.find("frames kept"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(output), std::string::npos) << r.out;
  MapReadOptions options;
  options.min_observations = 0;
  const Map mini = read_map(output, options);
  EXPECT_EQ(mini.frames.size(), 5u);
  ASSERT_FALSE(mini.landmarks.empty());
  for (const Landmark& l : mini.landmarks) {
    EXPECT_GE(l.observations.size(), 2u);
    for (const Observation& o : l.observations) {
      EXPECT_GE(o.frame_id, 2);
      EXPECT_LE(o.frame_id, 6);
    }
  }
  // Landmarks i in 0..29 seen by frames i..i+2 (mod 10) with >= 2 of them in 2..6:
  // i mod 10 in {1, ..., 5}: 5 per decade, 15 in all.
  EXPECT_EQ(mini.landmarks.size(), 15u);
}

TEST_F(CliSplit, RetriangulateWithOptions) {
  const std::string output = (dir_ / "mini_tri.txt").string();
  const RunResult r = run("split " + quote(input_) +
                          " --frames 0-9 --retriangulate --min-parallax 1.5 "
                          "--intrinsics 517.3,516.5,318.6,255.3 --min-observations 3 -o " +
                          quote(output));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("parallax"), std::string::npos) << r.out;
  const Map mini = read_map(output);
  EXPECT_EQ(mini.frames.size(), 10u);
  EXPECT_EQ(mini.landmarks.size(), 30u);
}

TEST_F(CliSplit, BadFramesTextIsAOneLineErrorNamingTheOption) {
  for (const std::string bad : {"abc", "5-2", "1-", "-", "1.5-3", "2:6", "a-b", "3"}) {
    const std::string output = (dir_ / "bad.txt").string();
    const RunResult r =
        run("split " + quote(input_) + " --frames " + quote(bad) + " -o " + quote(output));
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_EQ(line_count(r.err), 1u) << bad << ": " << r.err;
    EXPECT_NE(r.err.find("--frames"), std::string::npos) << bad << ": " << r.err;
    EXPECT_FALSE(fs::exists(output)) << bad;
  }
}

TEST_F(CliSplit, MissingInputNamesThePath) {
  const std::string missing = (dir_ / "no_such_map.txt").string();
  const std::string output = (dir_ / "out.txt").string();
  const RunResult r = run("split " + quote(missing) + " --frames 0-5 -o " + quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;
  EXPECT_EQ(line_count(r.err), 1u) << r.err;
  EXPECT_FALSE(fs::exists(output));
}

TEST_F(CliSplit, OutputEqualToInputIsRefused) {
  const std::string before = test::read_text(input_);
  const auto mtime = fs::last_write_time(input_);
  // The same file, spelled directly and through "./" and "..".
  const std::string spellings[] = {input_, (dir_ / "." / "map.txt").string(),
                                   (dir_ / ".." / dir_.filename() / "map.txt").string()};
  for (const std::string& output : spellings) {
    const RunResult r = run("split " + quote(input_) + " --frames 0-5 -o " + quote(output));
    EXPECT_NE(r.exit_code, 0) << output;
    EXPECT_NE(r.err.find("input"), std::string::npos) << r.err;
    EXPECT_EQ(line_count(r.err), 1u) << r.err;
  }
  EXPECT_EQ(test::read_text(input_), before);
  EXPECT_EQ(fs::last_write_time(input_), mtime);
}

TEST_F(CliSplit, OtherUsageErrors) {
  const std::string output = (dir_ / "out.txt").string();
  // Window with no frame of the map.
  RunResult r = run("split " + quote(input_) + " --frames 50-60 -o " + quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--frames"), std::string::npos) << r.err;
  // Retriangulation options without --retriangulate.
  r = run("split " + quote(input_) + " --frames 0-5 --min-parallax 3 -o " + quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--retriangulate"), std::string::npos) << r.err;
  // Bad intrinsics and parallax.
  r = run("split " + quote(input_) + " --frames 0-5 --retriangulate --intrinsics 1,2,3 -o " +
          quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("intrinsics"), std::string::npos) << r.err;
  r = run("split " + quote(input_) + " --frames 0-5 --retriangulate --min-parallax -1 -o " +
          quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("parallax"), std::string::npos) << r.err;
  r = run("split " + quote(input_) + " --frames 0-5 --min-observations 0 -o " + quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--min-observations"), std::string::npos) << r.err;
  r = run("split " + quote(input_) + " --frames 0-5 --retriangulate --min-observations 1 -o " +
          quote(output));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--min-observations"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(output));
}

TEST_F(CliSplit, HelpStatesUnitsAndFrames) {
  const RunResult r = run("split --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("degrees"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("pixels"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("world frame"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace lmalign
