// `lmalign align`: the real binary on synthetic maps (and on the real pair when present).
#include <nlohmann/json.hpp>

#include "lmalign/core/geometry.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/data_path.hpp"
#include "support/run_cli.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

class CliAlign : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    const Points3 pts = test::room_points(1500, 77);
    target_ = path("target.txt");
    source_ = path("source.txt");
    const Map target = test::map_from_points(pts, 78);
    write_map(target_, target);
    // The source is the same map expressed in a frame moved by T_true^-1.
    T_true_ = pose_from_xyz_rpy_deg(0.05, -0.04, 0.02, 1, -1, 4);
    write_map(source_, transform_map(target, T_true_.inverse()));
  }
  std::string source_, target_;
  Isometry3 T_true_;
};

TEST_F(CliAlign, PrintsOneRowPerStrategyAndWritesJson) {
  write_transform(path("gt.txt"), T_true_);
  // The paper's four, asked for explicitly (the default is the recommended strategy).
  const test::CliRun r = run("align " + source_ + " " + target_ + " --weight all --ground-truth " +
                             path("gt.txt") + " --json " + path("out/result.json") + " --history");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* s :
       {"base", "covariance", "observations", "distance", "rot deg", "absolute_mse"}) {
    EXPECT_NE(r.out.find(s), std::string::npos) << s << "\n" << r.out;
  }
  const auto j = nlohmann::json::parse(test::read_text(path("out/result.json")));
  ASSERT_EQ(j["results"].size(), 4u);
  const auto& base = j["results"][0];
  EXPECT_EQ(base["strategy"], "base");
  EXPECT_TRUE(base["right_basin"].get<bool>());
  EXPECT_LT(base["rotation_error_deg"].get<double>(), 1e-5);
  EXPECT_LT(base["translation_error_m"].get<double>(), 1e-6);
  EXPECT_EQ(base["history"].size(), base["iterations"].get<std::size_t>());
  // T_target_source in the JSON is the recovered transform.
  Isometry3 T = Isometry3::Identity();
  for (int rr = 0; rr < 4; ++rr)
    for (int c = 0; c < 4; ++c) T.matrix()(rr, c) = base["T_target_source"][rr][c].get<double>();
  EXPECT_LT(transform_error(T, T_true_).translation_m, 1e-6);
}

TEST_F(CliAlign, DefaultIsTheRecommendedStrategyAndStrategyListsSelectByName) {
  write_transform(path("gt.txt"), T_true_);
  const test::CliRun r = run("align " + source_ + " " + target_ + " --ground-truth " +
                             path("gt.txt") + " --json " + path("d.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto j = nlohmann::json::parse(test::read_text(path("d.json")));
  ASSERT_EQ(j["results"].size(), 1u);
  EXPECT_EQ(j["results"][0]["strategy"], "adaptive");
  EXPECT_TRUE(j["results"][0]["right_basin"].get<bool>());
  EXPECT_LT(j["results"][0]["translation_error_m"].get<double>(), 1e-3);

  const test::CliRun r2 = run("align " + source_ + " " + target_ +
                              " --strategy paper,shrink,robust_obs_4dof --json " + path("s.json"));
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  j = nlohmann::json::parse(test::read_text(path("s.json")));
  ASSERT_EQ(j["results"].size(), 6u);
  EXPECT_EQ(j["results"][0]["strategy"], "base");
  EXPECT_EQ(j["results"][4]["strategy"], "shrink");
  EXPECT_EQ(j["results"][5]["strategy"], "robust_obs_4dof");

  for (const std::string& bad :
       {std::string("--strategy robust"), std::string("--strategy base,base"),
        std::string("--strategy base --weight none")}) {
    const test::CliRun e = run("align " + source_ + " " + target_ + " " + bad);
    EXPECT_EQ(e.exit_code, 2) << bad << "\n" << e.out << e.err;
  }
}

TEST_F(CliAlign, PointToDistributionStrategiesRunWithTheMapsCovariances) {
  // p2d and robust_p2d use both maps' landmark covariances; the displacement rotates the
  // source's with its points.
  write_transform(path("gt.txt"), T_true_);
  const test::CliRun r = run("align " + source_ + " " + target_ +
                             " --strategy p2d,robust_p2d --displace 0.1,-0.05,0,0,0,8" +
                             " --ground-truth " + path("gt.txt") + " --json " + path("p.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("robust_p2d"), std::string::npos) << r.out;
  const auto j = nlohmann::json::parse(test::read_text(path("p.json")));
  ASSERT_EQ(j["results"].size(), 2u);
  EXPECT_EQ(j["results"][0]["strategy"], "p2d");
  EXPECT_EQ(j["results"][1]["strategy"], "robust_p2d");
  for (const auto& res : j["results"]) {
    EXPECT_TRUE(res["right_basin"].get<bool>()) << res["strategy"];
    EXPECT_LT(res["rotation_error_deg"].get<double>(), 1e-3) << res["strategy"];
    EXPECT_LT(res["translation_error_m"].get<double>(), 1e-4) << res["strategy"];
  }
}

TEST_F(CliAlign, IterationAndDistanceLimitsApplyToOwnStrategiesWhenGiven) {
  // Without the options, the preset runs to convergence (more than 2 iterations from 8 deg off);
  // with --max-iterations 2 it stops at 2. --max-distance caps the schedule: a cap below the
  // displacement's shift leaves no correspondence at the first level.
  const std::string base =
      "align " + source_ + " " + target_ + " --strategy shrink --displace 0.1,-0.05,0,0,0,8";
  const test::CliRun preset = run(base + " --json " + path("a.json"));
  ASSERT_EQ(preset.exit_code, 0) << preset.err;
  EXPECT_NE(preset.out.find("preset distance schedule"), std::string::npos) << preset.out;
  const auto a = nlohmann::json::parse(test::read_text(path("a.json")));
  EXPECT_GT(a["results"][0]["iterations"].get<int>(), 2);

  const test::CliRun limited = run(base + " --max-iterations 2 --json " + path("b.json"));
  ASSERT_EQ(limited.exit_code, 0) << limited.err;
  EXPECT_NE(limited.out.find("limited by the options above"), std::string::npos) << limited.out;
  const auto b = nlohmann::json::parse(test::read_text(path("b.json")));
  EXPECT_EQ(b["results"][0]["iterations"].get<int>(), 2);
  EXPECT_EQ(b["results"][0]["termination"], "max_iterations");

  const test::CliRun capped = run(base + " --max-distance 0.001 --json " + path("c.json"));
  ASSERT_EQ(capped.exit_code, 0) << capped.err;
  const auto c = nlohmann::json::parse(test::read_text(path("c.json")));
  EXPECT_EQ(c["results"][0]["termination"], "no_correspondences");
}

TEST_F(CliAlign, DisplaceIsUndoneInTheErrors) {
  write_transform(path("gt.txt"), T_true_);
  const test::CliRun r =
      run("align " + source_ + " " + target_ + " --weight none --displace 0,0.1,0,0,0,5" +
          " --ground-truth " + path("gt.txt") + " --json " + path("r.json") + " --aligned-out " +
          path("aligned.ply"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(test::read_text(path("r.json")));
  ASSERT_EQ(j["results"].size(), 1u);
  EXPECT_LT(j["results"][0]["rotation_error_deg"].get<double>(), 1e-5);
  EXPECT_LT(j["results"][0]["translation_error_m"].get<double>(), 1e-6);
  const std::string ply = test::read_text(path("aligned.ply"));
  EXPECT_EQ(ply.rfind("ply\n", 0), 0u);
  EXPECT_NE(ply.find("element vertex "), std::string::npos);
}

TEST_F(CliAlign, BadInputGivesOneLineErrorAndNonZeroExit) {
  struct Bad {
    std::string args;
    std::string expect;
  };
  for (const Bad& b :
       {Bad{"align " + path("missing.txt") + " " + target_, "missing.txt"},
        Bad{"align " + source_ + " " + target_ + " --displace 1,2,3", "--displace"},
        Bad{"align " + source_ + " " + target_ + " --displace 1,2,3,x,0,0", "'x'"},
        Bad{"align " + source_ + " " + target_ + " --ground-truth " + path("nope.txt"), "nope.txt"},
        Bad{"align " + source_ + " " + target_ + " --json " + source_, "refusing"},
        Bad{"align " + source_ + " " + target_ + " --k 0", "--k"},
        Bad{"align " + source_ + " " + target_ + " --weight cov", "--weight"}}) {
    const test::CliRun r = run(b.args);
    EXPECT_NE(r.exit_code, 0) << b.args;
    EXPECT_NE(r.err.find(b.expect), std::string::npos) << b.args << "\nstderr: " << r.err;
    if (r.err.rfind("lmalign: error:", 0) == 0) {
      EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    }
  }
  // A malformed map names the file and the line.
  { std::ofstream(path("bad.txt")) << "FRAME 0 0 0 0 1 0 0 0\nFRAME 1 0 0 0 1 0 0\n"; }
  const test::CliRun r = run("align " + path("bad.txt") + " " + target_);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("bad.txt:2:"), std::string::npos) << r.err;
  // The source file is untouched by the refused --json.
  EXPECT_NO_THROW(read_map(source_));
}

TEST_F(CliAlign, HelpNamesUnitsAndFrames) {
  const test::CliRun r = run("align --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* s : {"T_target_source", "metres", "degrees", "p_target"}) {
    EXPECT_NE(r.out.find(s), std::string::npos) << s;
  }
}

TEST_F(CliAlign, RealPairDemoRightBasin) {
  const std::string a = test::data_file("tum_fr1_desk/ground_truth_pair/desk_gt_a.txt");
  const std::string b = test::data_file("tum_fr1_desk/ground_truth_pair/desk_gt_b.txt");
  LMALIGN_REQUIRE_FILE(a);
  const test::CliRun r = run("align " + test::shell_quote(a) + " " + test::shell_quote(b) +
                             " --weight observations --displace 0,1,0.4,10,0,22.5 "
                             "--ground-truth identity --json " +
                             path("demo.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(test::read_text(path("demo.json")));
  EXPECT_TRUE(j["results"][0]["right_basin"].get<bool>());
  EXPECT_NEAR(j["results"][0]["rotation_error_deg"].get<double>(), 2.5, 0.3);
}

}  // namespace
}  // namespace lmalign
