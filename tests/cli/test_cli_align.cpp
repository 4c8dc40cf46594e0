// `lmalign align`: the real binary on synthetic maps (and on the real pair when present).
#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>
#include <string>

#include "lmalign/core/geometry.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/transform.hpp"
#include "support/cli_room_pair.hpp"
#include "support/data_path.hpp"
#include "support/run_cli.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

class CliAlign : public test::CliRoomPair {
 protected:
  void SetUp() override {
    CliRoomPair::SetUp();
    T_true_ = pose_from_xyz_rpy_deg(0.05, -0.04, 0.02, 1, -1, 4);
    write_room_pair(1500, 77, T_true_);
  }
  Isometry3 T_true_;
};

TEST_F(CliAlign, PrintsOneRowPerStrategyAndWritesJson) {
  write_transform(path("gt.txt"), T_true_);
  // The paper's four, asked for explicitly (the default is the recommended strategy). The JSON's
  // folder must exist (an output never creates folders: docs/robustness.md, "Outputs").
  std::filesystem::create_directories(path("out"));
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
                              " --strategy paper,mutual,robust_obs_4dof --json " + path("s.json"));
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  j = nlohmann::json::parse(test::read_text(path("s.json")));
  ASSERT_EQ(j["results"].size(), 6u);
  EXPECT_EQ(j["results"][0]["strategy"], "base");
  EXPECT_EQ(j["results"][4]["strategy"], "mutual");
  EXPECT_EQ(j["results"][5]["strategy"], "robust_obs_4dof");

  for (const std::string& bad :
       {std::string("--strategy robust"), std::string("--strategy base,base"),
        std::string("--strategy base --weight none")}) {
    const test::CliRun e = run("align " + source_ + " " + target_ + " " + bad);
    EXPECT_EQ(e.exit_code, 2) << bad << "\n" << e.out << e.err;
  }
}

TEST_F(CliAlign, SettingsAreSetCheckedAndListed) {
  // --set KEY=VALUE reaches any setting of the strategy; the JSON lists every setting.
  const std::string base = "align " + source_ + " " + target_ +
                           " --strategy robust_obs --displace 0.1,-0.05,0,0,0,8 --json ";
  const test::CliRun r = run(base + path("set.json") + " --set schedule.max_iterations=2" +
                             " --set kernel.scale_m=0.03");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(test::read_text(path("set.json")));
  EXPECT_EQ(j["results"][0]["iterations"].get<int>(), 2);
  EXPECT_EQ(j["results"][0]["settings"]["schedule.max_iterations"], "2");
  EXPECT_EQ(j["results"][0]["settings"]["kernel.scale_m"], "0.03");
  EXPECT_EQ(j["results"][0]["settings"]["schedule.levels_m"], "[inf, 1, 0.5, 0.25, 0.1, 0.05]");
  EXPECT_EQ(j["results"][0]["stages"]["schedule"], "distance_levels");

  // An unknown key names the nearest known one; a value outside its bound names key, value and
  // bound; both in one line, before any map is read.
  struct Bad {
    std::string set;
    std::string expect;
  };
  for (const Bad& b :
       {Bad{"schedule.max_iteration=2",
            "unknown setting 'schedule.max_iteration' (nearest: "
            "'schedule.max_iterations')"},
        Bad{"schedule.max_iterations=0",
            "schedule.max_iterations = 0 is outside its bound [1, "
            "2147483647]"},
        Bad{"kernel.confidence=weights", "kernel.confidence = 'weights' is not one of uniform"},
        Bad{"kernel.scale_m", "expected KEY=VALUE"}}) {
    const test::CliRun e = run("align " + path("missing.txt") + " " + target_ +
                               " --strategy robust_obs --set " + test::shell_quote(b.set));
    EXPECT_EQ(e.exit_code, 2) << b.set;
    EXPECT_NE(e.err.find(b.expect), std::string::npos) << b.set << "\n" << e.err;
    EXPECT_EQ(e.err.find('\n'), e.err.size() - 1) << "not one line: " << e.err;
  }

  // lmalign options: one setting per line, key first, then value, unit, bound, doc.
  const test::CliRun o = run("options robust_obs");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  std::istringstream lines(o.out);
  std::string line;
  bool found = false;
  while (std::getline(lines, line)) {
    if (line.rfind("schedule.max_iterations ", 0) != 0) continue;
    std::istringstream fields(line);
    std::string key, value, unit, bound;
    fields >> key >> value >> unit >> bound;
    EXPECT_EQ(value, "300");
    EXPECT_EQ(unit, "count");
    EXPECT_EQ(bound, "[1,");
    found = true;
  }
  EXPECT_TRUE(found) << o.out;
  EXPECT_NE(run("options robus_obs").err.find("nearest: 'robust_obs'"), std::string::npos);

  // A preset file: stages by name; an unknown one names the file, the line and the stage.
  {
    std::ofstream(path("mine.yaml")) << "doc: robust_obs with mutual pairs\ngroup: lmalign\n"
                                        "initialiser: guess\nmatcher: nearest\n"
                                        "rejectors: [mutual]\nkernel: cauchy\n"
                                        "estimator: umeyama\nschedule: distance_levels\n"
                                        "trust: inliers\nsettings:\n"
                                        "  kernel.confidence: observations\n";
  }
  const test::CliRun mine = run("align " + source_ + " " + target_ + " --strategy " +
                                path("mine.yaml") + " --json " + path("mine.json"));
  ASSERT_EQ(mine.exit_code, 0) << mine.err;
  EXPECT_EQ(nlohmann::json::parse(test::read_text(path("mine.json")))["results"][0]["strategy"],
            "mine");
  {
    std::ofstream(path("bad.yaml")) << "doc: x\ninitialiser: guess\nmatcher: nearst\n"
                                       "kernel: none\nestimator: umeyama\nschedule: pcl\n";
  }
  const test::CliRun bad =
      run("align " + source_ + " " + target_ + " --strategy " + path("bad.yaml"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find(path("bad.yaml") + ":3: unknown matcher stage 'nearst' (known: nearest"),
            std::string::npos)
      << bad.err;
}

TEST_F(CliAlign, IterationAndDistanceLimitsApplyToOwnStrategiesWhenGiven) {
  // Without the options, the preset runs to convergence (more than 2 iterations from 8 deg off);
  // with --max-iterations 2 it stops at 2. --max-distance caps the schedule: a cap below the
  // displacement's shift leaves no correspondence at the first level.
  const std::string base =
      "align " + source_ + " " + target_ + " --strategy robust_obs --displace 0.1,-0.05,0,0,0,8";
  const test::CliRun preset = run(base + " --json " + path("a.json"));
  ASSERT_EQ(preset.exit_code, 0) << preset.err;
  EXPECT_NE(preset.out.find("limits: the strategies' own"), std::string::npos) << preset.out;
  const auto a = nlohmann::json::parse(test::read_text(path("a.json")));
  EXPECT_GT(a["results"][0]["iterations"].get<int>(), 2);

  const test::CliRun limited = run(base + " --max-iterations 2 --json " + path("b.json"));
  ASSERT_EQ(limited.exit_code, 0) << limited.err;
  EXPECT_NE(limited.out.find("limits: max iterations 2, max distance -"), std::string::npos)
      << limited.out;
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

TEST_F(CliAlign, FreeScaleRecoversASimilarityAndReportsItsScaleError) {
  // The source is the target moved by S_true^-1, a similarity of scale 1 / 0.37 (covariances
  // scale by its square); --ground-truth takes S_true = [sR t; 0 1].
  const Similarity3 S_true{0.37, pose_from_xyz_rpy_deg(0.05, -0.04, 0.02, 1, -1, 4)};
  write_map(path("scaled.txt"), transform_map(read_map(target_), S_true.inverse()));
  {
    std::ofstream o(path("gt_sim.txt"));
    const Mat4 M = S_true.matrix();
    o.precision(17);
    for (int r = 0; r < 4; ++r)
      o << M(r, 0) << " " << M(r, 1) << " " << M(r, 2) << " " << M(r, 3) << "\n";
  }
  const test::CliRun r =
      run("align " + path("scaled.txt") + " " + target_ + " --strategy base,adaptive --scale free" +
          " --ground-truth " + path("gt_sim.txt") + " --json " + path("sim.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* s : {"scale", "scale sd", "scale err"}) {
    EXPECT_NE(r.out.find(s), std::string::npos) << s << "\n" << r.out;
  }
  const auto j = nlohmann::json::parse(test::read_text(path("sim.json")));
  ASSERT_EQ(j["results"].size(), 2u);
  for (const auto& e : j["results"]) {
    EXPECT_EQ(e["scale_mode"], "free");
    EXPECT_NEAR(e["scale"].get<double>(), 0.37, 0.0037) << e["strategy"];
    EXPECT_LT(e["scale_error"].get<double>(), 0.01) << e["strategy"];
    EXPECT_LT(e["rotation_error_deg"].get<double>(), 0.5) << e["strategy"];
    EXPECT_GT(e["scale_sd"].get<double>(), 0.0) << e["strategy"];
    EXPECT_NEAR(e["S_target_source"][0][0].get<double>(),
                e["scale"].get<double>() * e["T_target_source"][0][0].get<double>(), 1e-12);
  }
  EXPECT_NEAR(j["scale_true"].get<double>(), 0.37, 1e-12);
  // A fixed scale on the same files cannot reach the truth, and says how far its scale is off.
  const test::CliRun f = run("align " + path("scaled.txt") + " " + target_ +
                             " --strategy base --scale fixed --ground-truth " + path("gt_sim.txt"));
  ASSERT_EQ(f.exit_code, 0) << f.err;
  EXPECT_NE(f.out.find("scale err"), std::string::npos) << f.out;
  // Bad input: one line naming the option or the file.
  const test::CliRun bad = run("align " + source_ + " " + target_ + " --scale metric");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--scale: unknown scale mode 'metric' (known: auto, free, fixed)"),
            std::string::npos)
      << bad.err;
  {
    std::ofstream o(path("shear.txt"));
    o << "1 0.5 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  }
  const test::CliRun shear =
      run("align " + source_ + " " + target_ + " --ground-truth " + path("shear.txt"));
  EXPECT_NE(shear.exit_code, 0);
  EXPECT_NE(shear.err.find("shear.txt"), std::string::npos) << shear.err;
  EXPECT_NE(shear.err.find("neither a rotation nor a scaled rotation"), std::string::npos)
      << shear.err;
}

// Every reader's help lists every format of the registry (map_formats()).
TEST_F(CliAlign, HelpOfEveryReaderListsEveryFormat) {
  for (const char* command : {"align", "split", "convert"}) {
    SCOPED_TRACE(command);
    const test::CliRun r = run(std::string(command) + " --help");
    EXPECT_EQ(r.exit_code, 0);
    for (const MapFormatInfo& f : map_formats()) {
      EXPECT_NE(r.out.find(std::string(", ") + f.name), std::string::npos) << f.name << r.out;
    }
  }
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
