// `lmalign align --strategy global_robust_obs` from a start no local method recovers (150
// degrees, 2.5 m), and the trust verdict of every result, on the real pair with a known truth
// (identity).
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/data_path.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

using test::shell_quote;

class CliGlobalTrust : public test::CliTest {};

TEST_F(CliGlobalTrust, GlobalRecoversAFarStartAndTheVerdictTellsRightFromWrong) {
  const std::string d = test::data_file("tum_fr1_desk/ground_truth_pair");
  LMALIGN_REQUIRE_FILE(d + "/desk_gt_a.txt");
  const auto r =
      run("align " + shell_quote(d + "/desk_gt_a.txt") + " " + shell_quote(d + "/desk_gt_b.txt") +
          " --strategy global_robust_obs,base --displace 1.5,-2,0,0,0,150 --ground-truth identity"
          " --json " +
          shell_quote(path("a.json")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("trust"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(test::read_text(path("a.json")));
  ASSERT_EQ(j["results"].size(), 2u);
  const auto& global = j["results"][0];
  const auto& base = j["results"][1];
  ASSERT_EQ(global["strategy"], "global_robust_obs");
  EXPECT_TRUE(global["right_basin"].get<bool>());
  EXPECT_LT(global["rotation_error_deg"].get<double>(), 1.5);
  EXPECT_LT(global["translation_error_m"].get<double>(), 0.03);
  EXPECT_TRUE(global["trustworthy"].get<bool>()) << global["trust_reason"];
  EXPECT_EQ(global["covariance_6x6"].size(), 36u);
  // The paper's base ICP ends in a wrong basin from there, and the verdict says so.
  EXPECT_FALSE(base["right_basin"].get<bool>());
  EXPECT_FALSE(base["trustworthy"].get<bool>());
  EXPECT_NE(base["trust_reason"].get<std::string>().find("inlier"), std::string::npos);
}

}  // namespace
}  // namespace lmalign
