// `lmalign eval-trajectory` through the real binary: ATE/RPE of the paper authors' own
// odometry against groundtruth.txt, plots and outputs, and bad input. (Always built: it does not
// need the optional map builder.)
#include <algorithm>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "support/data_path.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

using test::shell_quote;

class CliEvalTrajectory : public test::CliTest {};

TEST_F(CliEvalTrajectory, EvalTrajectoryOfTheAuthorsMap) {
  const std::string d = test::data_file("tum_fr1_desk");
  LMALIGN_REQUIRE_FILE(d + "/map_fr1_desk.txt");
  const auto r =
      run("eval-trajectory " + shell_quote(d + "/map_fr1_desk.txt") + " " +
          shell_quote(d + "/groundtruth.txt") + " --frame-times " +
          shell_quote(d + "/frame_times.txt") + " --plot " + shell_quote(path("plot.svg")) +
          " --aligned-out " + shell_quote(path("aligned.txt")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("associated pairs: 240"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ATE"), std::string::npos);
  EXPECT_NE(r.out.find("RPE"), std::string::npos);
  EXPECT_NE(test::read_text(path("plot.svg")).find("<polyline"), std::string::npos);
  // One line per associated pose (the authors' map has two frames made from the same image, so
  // the file repeats a time stamp and read_tum_trajectory, which is strict, would refuse it).
  const std::string aligned = test::read_text(path("aligned.txt"));
  EXPECT_EQ(std::count(aligned.begin(), aligned.end(), '\n'), 241);  // + header comment
}

TEST_F(CliEvalTrajectory, EvalTrajectoryBadInputNamesFileAndLine) {
  const std::string d = test::data_file("tum_fr1_desk");
  LMALIGN_REQUIRE_FILE(d + "/groundtruth.txt");
  std::ofstream(path("est.txt")) << "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n";
  const auto r = run(shell_quote(path("est.txt")).insert(0, "eval-trajectory ") + " " +
                     shell_quote(d + "/groundtruth.txt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find(path("est.txt") + ":2:"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace lmalign
