// `lmalign build-map` through the real binary (eval-trajectory alone: tests/cli).
#ifdef LMALIGN_CLI_PATH

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/data_path.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

using test::shell_quote;

class VoCli : public test::CliTest {};

TEST_F(VoCli, BuildMapOnRealFramesThenEvaluate) {
  const std::string d = test::data_file("tum_fr1_desk");
  LMALIGN_REQUIRE_FILE(d + "/rgb.txt");
  const auto r = run("build-map " + shell_quote(d) + " -o " + shell_quote(path("map.txt")) +
                     " --init-from-groundtruth --max-frames 9 --camera fr1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("keyframes:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("observations per landmark"), std::string::npos) << r.out;
  const Map map = read_map(path("map.txt"));
  EXPECT_GT(map.landmarks.size(), 100u);
  const Trajectory t = read_tum_trajectory(path("map_keyframes.tum.txt"));
  EXPECT_EQ(t.size(), map.frames.size());
  const auto e = run("eval-trajectory " + shell_quote(path("map_keyframes.tum.txt")) + " " +
                     shell_quote(d + "/groundtruth.txt"));
  EXPECT_EQ(e.exit_code, 0) << e.err;
  // A frame beyond the 9 present images: the error names the missing image.
  const auto bad = run("build-map " + shell_quote(d) + " -o " + shell_quote(path("m2.txt")) +
                       " --max-frames 10");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("1305031453.659600.png"), std::string::npos) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(path("m2.txt")));
}

}  // namespace
}  // namespace lmalign

#endif  // LMALIGN_CLI_PATH
