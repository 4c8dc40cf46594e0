// `lmalign build-map` through the real binary (eval-trajectory alone: tests/cli).
#ifdef LMALIGN_HAVE_CLI

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

// `lmalign` hands build-map over to its helper lmalign-build-map, arguments untouched (--help
// included), and never loads OpenCV itself (main.cpp; docs/cli.md).
TEST_F(VoCli, BuildMapRunsInTheHelperAndLmalignDoesNotLoadOpenCv) {
  const auto help = run("build-map --help");
  ASSERT_EQ(help.exit_code, 0) << help.err;
  EXPECT_NE(help.out.find("--init-from-groundtruth"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("build-map"), std::string::npos) << help.out;
  // Listed among lmalign's commands.
  const auto top = run("--help");
  ASSERT_EQ(top.exit_code, 0) << top.err;
  EXPECT_NE(top.out.find("build-map"), std::string::npos) << top.out;
  // A usage error is the helper's, with lmalign's exit code and message format.
  const auto bad = run("build-map");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("lmalign: error:"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("SEQUENCE"), std::string::npos) << bad.err;
  // The dynamic loader's own list of what it loads (glibc LD_DEBUG): no OpenCV for lmalign.
  const auto libs = run_with_env("LD_DEBUG=libs", "--version");
  ASSERT_EQ(libs.exit_code, 0) << libs.err;
  EXPECT_NE(libs.err.find("libstdc++"), std::string::npos) << libs.err;  // the list is there
  EXPECT_EQ(libs.err.find("libopencv"), std::string::npos) << libs.err;
  EXPECT_EQ(libs.err.find("libceres"), std::string::npos) << libs.err;
}

// Without the helper beside it, build-map fails with a message naming the missing file.
TEST_F(VoCli, BuildMapWithoutItsHelperSaysWhatIsMissing) {
  const std::string copy = path("lmalign");
  std::filesystem::copy_file(LMALIGN_CLI_PATH, copy);
  std::filesystem::permissions(copy, std::filesystem::perms::owner_all);
  const int status = std::system((shell_quote(copy) + " build-map x -o y >" +
                                  shell_quote(path("out")) + " 2>" + shell_quote(path("err")))
                                     .c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  const std::string err = test::read_text(path("err"));
  EXPECT_NE(err.find(path("lmalign-build-map")), std::string::npos) << err;
  EXPECT_NE(err.find("could not be started"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(path("y")));
}

}  // namespace
}  // namespace lmalign

#endif  // LMALIGN_HAVE_CLI
