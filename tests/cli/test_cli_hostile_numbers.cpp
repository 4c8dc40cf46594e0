// The real `lmalign` binary on extreme but finite numbers (docs/robustness.md, "Supported
// range"): a landmark far away in an otherwise good map (within the range: aligned; beyond it:
// left out, counted, named in the trust reason), option values, initial guesses and priors
// beyond the range (one-line errors naming the option and value), the merge's manifest, and
// failures that are not lmalign's own (out of memory): every case ends in exit 0 with a result
// or exit 2 with one line on stderr, never a crash.
#include <sys/resource.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmalign/core/geometry.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/presets.hpp"
#include "support/run_cli.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;
using test::expect_one_line_error;
using test::shell_quote;

class CliHostileNumbers : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    target_ = test::map_from_points(test::room_points(500, 61), 62);
    // Every landmark seen at least twice: none is dropped on load (--min-observations 2).
    for (Landmark& l : target_.landmarks) {
      if (l.observations.size() < 2) l.observations.push_back(l.observations.front());
    }
    T_true_ = pose_from_xyz_rpy_deg(0.2, -0.1, 0.02, 0.5, -0.3, 30.0);
    source_ = transform_map(target_, T_true_.inverse());
    write_map(path("target.txt"), target_);
    write_map(path("source.txt"), source_);
    write_transform(path("gt.txt"), T_true_);
  }
  std::string st() const { return path("source.txt") + " " + path("target.txt"); }
  nlohmann::json results(const std::string& json) const {
    return nlohmann::json::parse(test::read_text(json))["results"];
  }
  Map target_, source_;
  Isometry3 T_true_;
};

TEST_F(CliHostileNumbers, AFarSourceLandmarkIsAlignedWithinTheRangeAndLeftOutBeyondIt) {
  // A stereo landmark at near-zero disparity lands at fx b / d. Within the supported range
  // (1e15 m) it is kept and finds no partner; beyond it, it is left out and counted. Either way
  // the default (adaptive) aligns the rest: before, 1e9 m and beyond ended in SIGSEGV.
  for (const double far : {1e9, 1e12, 1e16, 1e150, 1e300}) {
    Map s = source_;
    s.landmarks[0].p_world.x() = far;  // landmark 0 is among the search's samples
    write_map(path("far.txt"), s);
    const std::string what = "x = " + std::to_string(far);
    const test::CliRun r = run("align " + path("far.txt") + " " + path("target.txt") +
                               " --ground-truth " + path("gt.txt") + " --json " + path("far.json"));
    ASSERT_EQ(r.exit_code, 0) << what << ": " << r.err;
    const nlohmann::json e = results(path("far.json"))[0];
    EXPECT_EQ(e["strategy"], "adaptive");
    EXPECT_TRUE(e["right_basin"].get<bool>()) << what;
    EXPECT_LT(e["rotation_error_deg"].get<double>(), 0.5) << what;
    EXPECT_TRUE(e["trustworthy"].get<bool>()) << what << ": " << e["trust_reason"];
    const bool left_out = far > 1e15;
    EXPECT_EQ(e["source_landmarks_left_out"].get<int>(), left_out ? 1 : 0) << what;
    EXPECT_EQ(e["target_landmarks_left_out"].get<int>(), 0) << what;
    const std::string reason = e["trust_reason"];
    EXPECT_EQ(reason.find("1 source landmark beyond the supported range") != std::string::npos,
              left_out)
        << what << ": " << reason;
    // The table says so too, for a trusted result.
    EXPECT_EQ(r.out.find("trusted: ok; 1 source landmark beyond") != std::string::npos, left_out)
        << r.out;
  }
}

TEST_F(CliHostileNumbers, EveryStrategyLeavesOutLandmarksBeyondTheRangeOfEitherMap) {
  Map s = source_;
  s.landmarks[3].p_world = Vec3(0.5, 1e300, -1e300);
  Map t = target_;
  t.landmarks[4].p_world.z() = -1e20;
  write_map(path("far_s.txt"), s);
  write_map(path("far_t.txt"), t);
  const test::CliRun r = run("align " + path("far_s.txt") + " " + path("far_t.txt") +
                             " --strategy all --json " + path("all.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json all = results(path("all.json"));
  EXPECT_EQ(all.size(), preset_names().size());  // every preset
  for (const auto& e : all) {
    EXPECT_EQ(e["source_landmarks_left_out"].get<int>(), 1) << e["strategy"];
    EXPECT_EQ(e["target_landmarks_left_out"].get<int>(), 1) << e["strategy"];
    const std::string reason = e["trust_reason"];
    EXPECT_NE(reason.find("1 source landmark and 1 target landmark beyond the supported range "
                          "(|coordinate| > 1e+15 m) left out"),
              std::string::npos)
        << e["strategy"] << ": " << reason;
    for (const auto& row : e["T_target_source"]) {
      for (const auto& v : row) EXPECT_TRUE(v.is_number()) << e["strategy"];  // finite
    }
  }
  // A map entirely beyond the range is refused naming the side.
  Map gone = source_;
  for (Landmark& l : gone.landmarks) l.p_world.x() = 1e300;
  write_map(path("gone.txt"), gone);
  expect_one_line_error(run("align " + path("gone.txt") + " " + path("target.txt")),
                        "every source landmark (500) is beyond the supported range", "all far");
}

TEST_F(CliHostileNumbers, OptionValuesBeyondTheRangeAreOneLineErrorsNamingThem) {
  Isometry3 far = Isometry3::Identity();
  far.translation() = Vec3(1e308, 0, 0);
  write_transform(path("g308.txt"), far);
  far.translation() = Vec3(0, 0, -1e20);
  write_transform(path("g20.txt"), far);
  struct Bad {
    std::string args, expect;
  };
  for (const Bad& b : std::vector<Bad>{
           {"--displace 1e308,0,0,0,0,0",
            "--displace 1e308,0,0,0,0,0: translation (1e+308, 0, 0) m is beyond the supported "
            "range (|coordinate| <= 1e+15 m)"},
           {"--displace 0,-2e15,0,0,0,0", "--displace 0,-2e15,0,0,0,0: translation"},
           {"--displace 0,0,0,0,1e300,0",
            "--displace 0,0,0,0,1e300,0: 1e+300 degrees is beyond the supported range"},
           {"--initial-guess " + path("g308.txt") + " --prior-sigma 1,1",
            "--initial-guess " + path("g308.txt") + ": translation (1e+308, 0, 0) m is beyond"},
           {"--initial-guess " + path("g20.txt"), "--initial-guess " + path("g20.txt")},
           {"--initial-guess " + path("g20.txt") + " --strategy base",
            "--initial-guess " + path("g20.txt")},
           {"--prior-sigma 1,1e308",
            "--prior-sigma 1,1e308: prior translation sigma must be within the supported range "
            "[1e-09, 1e+15] metres, got 1e+308"},
           {"--prior-sigma 1e-300,1", "--prior-sigma 1e-300,1: prior rotation sigma"},
           {"--prior-sigma 1e300,1", "--prior-sigma 1e300,1: prior rotation sigma"},
           {"--ground-truth " + path("g308.txt"), "--ground-truth " + path("g308.txt")},
       }) {
    expect_one_line_error(run("align " + st() + " " + b.args), b.expect, b.args);
  }
}

// Issue 41's bad input: a zero, negative or NaN sigma and a guess that is not a rigid transform
// are one line each; a guess that puts the maps kilometres apart, with an ordinary prior, gives
// a result that is not trusted and says where the maps put the source.
TEST_F(CliHostileNumbers, BadPriorsAreOneLineErrorsAndAGuessKilometresOffIsNeverTrusted) {
  {
    std::ofstream f(path("scaled.txt"));
    f << "2 0 0 0\n0 2 0 0\n0 0 2 0\n0 0 0 1\n";  // a similarity, not a rigid transform
  }
  struct Bad {
    std::string args, expect;
  };
  for (const Bad& b : std::vector<Bad>{
           {"--prior-sigma 0,0.3", "--prior-sigma 0,0.3: prior rotation sigma"},
           {"--prior-sigma 1,0", "--prior-sigma 1,0: prior translation sigma"},
           {"--prior-sigma -1,0.3", "--prior-sigma -1,0.3: prior rotation sigma"},
           {"--prior-sigma 1,-0.3", "--prior-sigma 1,-0.3: prior translation sigma"},
           {"--prior-sigma nan,0.3", "--prior-sigma \"nan,0.3\": 'nan' is not a finite number"},
           {"--prior-sigma 1,nan", "--prior-sigma \"1,nan\": 'nan' is not a finite number"},
           {"--initial-guess " + path("scaled.txt") + " --prior-sigma 1,0.3", path("scaled.txt")},
       }) {
    expect_one_line_error(run("align " + st() + " " + b.args), b.expect, b.args);
  }
  Isometry3 far = T_true_;
  far.translation() += Vec3(3000.0, -1500.0, 0.0);
  write_transform(path("km.txt"), far);
  const test::CliRun r = run("align " + st() + " --initial-guess " + path("km.txt") +
                             " --prior-sigma 1,0.3 --json " + path("km.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json e = results(path("km.json")).at(0);
  EXPECT_FALSE(e["trustworthy"].get<bool>()) << e["trust_reason"];
  for (const auto& row : e["T_target_source"]) {
    for (const auto& v : row) EXPECT_TRUE(v.is_number());  // finite
  }
}

TEST_F(CliHostileNumbers, AGuessAndPriorAtTheEdgeOfTheRangeGiveAResult) {
  // No intermediate overflows at the edge of the range. So wide a prior bounds nothing: the
  // search is global and finds the truth; a tight one about a guess that far finds nothing, and
  // the strategies that start from the guess end untrusted; all with finite estimates.
  Isometry3 edge = Isometry3::Identity();
  edge.translation() = Vec3(1e15, -1e15, 1e15);
  write_transform(path("edge.txt"), edge);
  struct Case {
    std::string args;
    bool trusted;
  };
  for (const Case& c : std::vector<Case>{
           {"--initial-guess " + path("edge.txt") + " --prior-sigma 1e15,1e15", true},
           {"--initial-guess " + path("edge.txt") + " --prior-sigma 1e-9,1e-9", false},
           {"--initial-guess " + path("edge.txt") + " --strategy paper,robust_obs,mutual", false},
       }) {
    const test::CliRun r = run("align " + st() + " " + c.args + " --json " + path("edge.json"));
    ASSERT_EQ(r.exit_code, 0) << c.args << ": " << r.err;
    for (const auto& e : results(path("edge.json"))) {
      for (const auto& row : e["T_target_source"]) {
        for (const auto& v : row) EXPECT_TRUE(v.is_number()) << c.args << " " << e["strategy"];
      }
      EXPECT_EQ(e["trustworthy"].get<bool>(), c.trusted)
          << c.args << " " << e["strategy"] << ": " << e["trust_reason"];
    }
  }
  // A displacement to the range's edge moves the source's landmarks beyond it: every one left
  // out, a one-line error naming the side.
  const test::CliRun far = run("align " + st() + " --displace 1e15,1e15,-1e15,0,0,0");
  EXPECT_EQ(far.exit_code, 2) << far.err;
  EXPECT_NE(far.err.find("every source landmark"), std::string::npos) << far.err;
}

TEST_F(CliHostileNumbers, OutOfMemoryIsOneLineAndExitCodeTwo) {
  if (lmalign_test_cli_sanitized()) {
    GTEST_SKIP() << "AddressSanitizer reserves terabytes of address space: no ulimit -v under it";
  }
  // An allocation that fails (here ten million landmarks under a 400 MB address-space limit) is a
  // std::bad_alloc, not lmalign's own error: one line, exit 2 (before, exit 3).
  const std::string command = "ulimit -v 400000; " + shell_quote(LMALIGN_CLI_PATH) +
                              " simulate --scene road --landmarks 10000000 -o " +
                              shell_quote(path("sim")) + " >/dev/null 2>" +
                              shell_quote(path("err.txt"));
  const int status = std::system(("sh -c " + shell_quote(command)).c_str());
  ASSERT_TRUE(WIFEXITED(status));
  test::CliRun r;
  r.exit_code = WEXITSTATUS(status);
  r.err = test::read_text(path("err.txt"));
  expect_one_line_error(r, "out of memory", "simulate 1e7 landmarks in 400 MB");
}

#ifdef LMALIGN_CLI_HAS_MERGE
TEST_F(CliHostileNumbers, MergeManifestValuesBeyondTheRangeAreOneLineErrorsNamingTheLine) {
  const std::string m = path("source.txt");
  struct Case {
    std::string name, entry, expect;
  } cases[] = {
      {"t308", "T_world_map: [[1,0,0,1e308],[0,1,0,0],[0,0,1,0],[0,0,0,1]], prior_sigma: [2, 0.5]",
       "maps[0].T_world_map: translation (1e+308, 0, 0) m is beyond the supported range"},
      {"t20", "T_world_map: [[1,0,0,0],[0,1,0,-1e20],[0,0,1,0],[0,0,0,1]], prior_sigma: [2, 0.5]",
       "maps[0].T_world_map: translation (0, -1e+20, 0) m"},
      {"sigma_t", "T_world_map: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], prior_sigma: [2, 1e308]",
       "maps[0].prior_sigma[1] (translation_m): 1e+308 m is outside the supported range of a "
       "standard deviation ([1e-09, 1e+15] m)"},
      {"sigma_r", "T_world_map: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], prior_sigma: [1e16, 1]",
       "maps[0].prior_sigma[0] (rotation_deg): 1e+16 degrees is outside the supported range"},
      {"covariance",
       "T_world_map: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], prior_covariance: "
       "[[1e300,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]",
       "maps[0].prior_covariance[0][0]: standard deviation: 1e+150 m is outside the supported"},
  };
  for (const Case& c : cases) {
    const std::string manifest = path(c.name + ".yaml");
    std::ofstream(manifest) << "maps:\n  - {name: a, path: " << m << ", " << c.entry
                            << "}\n  - {name: b, path: " << path("target.txt") << "}\n";
    const test::CliRun r = run("merge " + shell_quote(manifest) + " -o " + shell_quote(path("o")));
    expect_one_line_error(r, manifest + ":2: " + c.expect, c.name);
    EXPECT_FALSE(fs::exists(path("o") + "/poses.yaml")) << c.name;
  }
}

TEST_F(CliHostileNumbers, MergeLeavesOutALandmarkBeyondTheRangeAndCountsIt) {
  Map s = source_;
  s.landmarks[0].p_world = Vec3(1e300, 0, 0);
  write_map(path("far.txt"), s);
  const std::string manifest = path("m.yaml");
  std::ofstream(manifest) << "maps:\n  - {name: far, path: " << path("far.txt")
                          << "}\n  - {name: near, path: " << path("target.txt") << "}\n";
  const test::CliRun r =
      run("merge " + shell_quote(manifest) + " -o " + shell_quote(path("o")) + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("map 'far': 1 landmark(s) beyond the supported range (|coordinate| > "
                       "1e+15 m) left out"),
            std::string::npos)
      << r.err;
  const nlohmann::json summary =
      nlohmann::json::parse(test::read_text(path("o") + "/summary.json"));
  EXPECT_EQ(summary["landmarks_left_out"].get<int>(), 1);
  EXPECT_EQ(summary["num_edges_used"].get<int>(), 1);
  const Map merged = read_map(path("o") + "/merged_map.txt", MapReadOptions{0});
  EXPECT_EQ(merged.landmarks.size(), 2 * target_.landmarks.size() - 1);
  EXPECT_NE(test::read_text(path("o") + "/edges.csv").find(",1,1,0,"), std::string::npos)
      << test::read_text(path("o") + "/edges.csv");  // trusted, used, not rejected
}
#endif

}  // namespace
}  // namespace lmalign
