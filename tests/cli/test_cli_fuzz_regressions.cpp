// Replays fuzz/regressions/cli_options/ and fuzz/corpus/cli_options/ through the real `lmalign`
// binary with the oracle of fuzz/cli_options_check.hpp (the fuzz target runs the same command in
// process): exit 0, or exit 2 with one line on stderr. In every test build, including the
// AddressSanitizer + UndefinedBehaviorSanitizer one (docs/robustness.md).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "../../fuzz/cli_options_check.hpp"
#include "support/fuzz_inputs.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

using test::shell_quote;

using CliFuzzRegressions = test::CliTest;

TEST_F(CliFuzzRegressions, OptionInputsSatisfyTheOracle) {
  const std::string dir = dir_.string();
  fuzz::write_cli_fuzz_maps(dir);
  const std::vector<std::filesystem::path> files = test::fuzz_inputs("cli_options");
  for (const std::filesystem::path& file : files) {
    std::fprintf(stderr, "replaying %s\n", file.c_str());
    const fuzz::CliOptionsInput input = fuzz::decode_cli_options(test::file_bytes(file), dir);
    fuzz::write_cli_fuzz_files(input, dir);
    std::string args =
        "align " + shell_quote(dir + "/source.txt") + " " + shell_quote(dir + "/target.txt");
    for (const std::string& a : input.args) args += " " + shell_quote(a);
    const test::CliRun r = run(args);
    fuzz::check_cli_outcome(r.exit_code, r.err);
  }
  EXPECT_GE(files.size(), 5u) << "no fuzz inputs under " << test::fuzz_dir();
}

// The target keeps each input's work within the presets' own budgets (an input has 10-30 s under
// the sanitizers): --set of a count above every preset's default, or of a yaw step below it, is
// not passed; anything else is, values the CLI refuses included.
TEST(CliFuzzOptions, SettingsThatRaiseTheWorkAreNotPassed) {
  // Whether the line's value reaches the command line.
  const auto passed = [](const std::string& line) {
    const std::vector<std::string> args = fuzz::decode_cli_options(line + "\n", "/tmp").args;
    const std::string value = line.substr(line.find(' ') + 1);
    return std::find(args.begin(), args.end(), value) != args.end();
  };

  EXPECT_TRUE(passed("set search.round1_iterations=15"));
  EXPECT_FALSE(passed("set search.round1_iterations=100000"));
  EXPECT_FALSE(passed("set schedule.max_iterations=2147483647"));
  EXPECT_FALSE(passed("set estimate.half_sample_planes=1000"));
  EXPECT_TRUE(passed("set init.yaw_step_deg=10"));
  EXPECT_FALSE(passed("set init.yaw_step_deg=0.001"));
  EXPECT_TRUE(passed("set match.chi2_threshold=1e308"));  // no work budget
  EXPECT_TRUE(passed("set match.k=0"));                   // refused by the CLI: passed
  EXPECT_TRUE(passed("set no.such_key=1"));
  EXPECT_FALSE(passed("strategy all"));
  EXPECT_FALSE(passed("max-iterations 501"));
  // The default runs the complete search: the targets' smaller budget is passed last.
  const std::vector<std::string> args = fuzz::decode_cli_options("k 5\n", "/tmp").args;
  ASSERT_GE(args.size(), 2u);
  EXPECT_EQ(args[args.size() - 2], "--set");
  EXPECT_EQ(args.back(), "search.round1_keep=4");
  EXPECT_EQ(fuzz::decode_cli_options("strategy base\n", "/tmp").args.size(), 2u);
}

}  // namespace
}  // namespace lmalign
