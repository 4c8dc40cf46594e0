// `lmalign options --markdown`: docs/settings.md is generated from the tables, and stays so.
#include <string>

#include <gtest/gtest.h>

#include "support/run_cli.hpp"

namespace lmalign {
namespace {

class CliOptions : public test::CliTest {};

TEST_F(CliOptions, SettingsPageIsUpToDate) {
  const test::CliRun r = run("options --markdown");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string page = test::read_text(std::string(LMALIGN_SOURCE_DIR) + "/docs/settings.md");
  ASSERT_FALSE(page.empty()) << "docs/settings.md is missing";
  // On failure: lmalign options --markdown > docs/settings.md
  EXPECT_TRUE(r.out == page) << "docs/settings.md is out of date: regenerate it with "
                                "`lmalign options --markdown > docs/settings.md`";
  // The page holds every preset's settings and the experiment config's keys, from the tables.
  EXPECT_NE(r.out.find("### robust_obs"), std::string::npos);
  EXPECT_NE(r.out.find("| `match.k` |"), std::string::npos);
  EXPECT_NE(r.out.find("| `max_distance_m` | every | none | m | > 0 or inf |"), std::string::npos);
  EXPECT_NE(r.out.find("| `up_axis` | random | z | - | one of x, y, z |"), std::string::npos);
  EXPECT_NE(r.out.find("a case index or &lt;experiment>/&lt;label>"), std::string::npos);
}

TEST_F(CliOptions, MarkdownOrAPresetIsRequiredButNotBoth) {
  test::expect_one_line_error(run("options"), "give a PRESET, or --markdown", "no preset");
  test::expect_one_line_error(run("options base --markdown"), "give no PRESET", "both");
}

}  // namespace
}  // namespace lmalign
