// Experiment configs: strict YAML with file:line errors, defaults, paths, and the resolved copy.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/experiment/runner.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

const char* kMinimal = R"(source: a.txt
target: b.txt
experiments:
  - name: yaws
    type: yaw
    yaw_deg: [0, 10]
)";

ExperimentConfig parse(const std::string& text, const std::string& data_dir = "/data") {
  ConfigLoadOptions o;
  o.data_dir = data_dir;
  return parse_experiment_config(text, "cfg.yaml", "/base/dir", o);
}

/// The ParseError message for `text`; fails the test if it parses.
std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const ParseError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ParseError for:\n" << text;
  return "";
}

TEST(ExperimentConfig, MinimalConfigGetsThePapersDefaults) {
  const ExperimentConfig c = parse(kMinimal);
  EXPECT_EQ(c.source.path, "/base/dir/a.txt");
  EXPECT_EQ(c.target.path, "/base/dir/b.txt");
  EXPECT_FALSE(c.source.split);
  EXPECT_EQ(c.source.min_observations, 2u);
  EXPECT_EQ(c.ground_truth.kind, GroundTruthSpec::Kind::kNone);
  EXPECT_FALSE(c.has_ground_truth());
  EXPECT_EQ(c.strategies, preset_names("paper"));
  EXPECT_EQ(c.k, 5);
  // No limits given: every strategy keeps its own (the paper's: 150 iterations, no distance cap).
  EXPECT_FALSE(c.max_iterations.has_value());
  EXPECT_FALSE(c.max_distance_m.has_value());
  EXPECT_EQ(c.success.rotation_deg, 5.0);
  EXPECT_EQ(c.success.translation_m, 0.10);
  EXPECT_EQ(c.success.score_m2, 0.0037);
  ASSERT_EQ(c.experiments.size(), 1u);
  EXPECT_EQ(c.experiments[0].name, "yaws");
  EXPECT_EQ(c.experiments[0].type, ExperimentType::kYaw);
  EXPECT_EQ(c.experiments[0].k, 5);
  EXPECT_EQ(c.experiments[0].line, 4u);
  EXPECT_EQ(c.experiments[0].yaw_deg, (std::vector<double>{0, 10}));
}

TEST(ExperimentConfig, PathsAreRelativeToTheConfigAndExpandLmalignData) {
  const ExperimentConfig c = parse(R"(source: ${LMALIGN_DATA}/pair/a.txt
target: {map: ../maps/full.txt, frames: [120, 239], min_observations: 3}
ground_truth: gt/T.txt
experiments: [{name: e, type: yaw, yaw_deg: [1]}]
)");
  EXPECT_EQ(c.source.path, "/data/pair/a.txt");
  EXPECT_EQ(c.target.path, "/base/maps/full.txt");
  EXPECT_TRUE(c.target.split);
  EXPECT_EQ(c.target.first_frame_id, 120);
  EXPECT_EQ(c.target.last_frame_id, 239);
  EXPECT_EQ(c.target.min_observations, 3u);
  EXPECT_EQ(c.ground_truth.kind, GroundTruthSpec::Kind::kFile);
  EXPECT_EQ(c.ground_truth.path, "/base/dir/gt/T.txt");
}

TEST(ExperimentConfig, LmalignDataWithoutADataFolderIsAnErrorNamingTheLine) {
  try {
    parse(
        "target: b.txt\nsource: ${LMALIGN_DATA}/a.txt\nexperiments: [{name: e, type: yaw, yaw_deg: "
        "[1]}]\n",
        "");
    FAIL() << "expected ParseError";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 2u);
    EXPECT_NE(std::string(e.what()).find("LMALIGN_DATA"), std::string::npos) << e.what();
  }
}

TEST(ExperimentConfig, ErrorsNameFileLineKeyAndWhatWasExpected) {
  struct Bad {
    std::string yaml;
    std::string message;  // exact prefix of what()
  };
  const std::string head = "source: a.txt\ntarget: b.txt\nexperiments:\n";
  const std::vector<Bad> cases{
      // The issue's example: a scalar where a list of numbers is expected.
      {head + "  - {name: t1, type: k, k_values: [1, 5]}\n  - name: t2\n    type: yaw\n    "
              "yaw_deg: 30\n",
       "cfg.yaml:7: experiments[1].yaw_deg: expected a list of numbers"},
      {head + "  - {name: t, type: yaw, yaw_deg: [0, x]}\n",
       "cfg.yaml:4: experiments[0].yaw_deg[1]: expected a finite number, got 'x'"},
      {"source: a.txt\ntarget: b.txt\nfoo: 1\nexperiments: []\n",
       "cfg.yaml:3: unknown key 'foo' (expected one of: description, source, target"},
      {"source: a.txt\ntarget: b.txt\nk: 5\nk: 7\nexperiments: []\n",
       "cfg.yaml:4: duplicate key 'k' (first at line 3)"},
      {"source: a.txt\nexperiments: [{name: e, type: yaw, yaw_deg: [1]}]\n",
       "cfg.yaml:1: missing key 'target'"},
      {head + "  - {name: e, type: yaw, yaw_deg: [1], strategies: [base, cov]}\n",
       "cfg.yaml:4: experiments[0].strategies[1]: unknown strategy 'cov'"},
      {head + "  - {name: e, type: yaw, yaw_deg: [1], k: 0}\n",
       "cfg.yaml:4: experiments[0].k: expected an integer in [1, 4096], got 0"},
      {"source: a.txt\ntarget: b.txt\nmax_distance_m: -1\nexperiments: []\n",
       "cfg.yaml:3: max_distance_m: must be > 0, got -1"},
      {head + "  - name: e\n    type: xy\n    offsets_m: {+X+Y: [0.5]}\n    escalate: {start_m: "
              "0.25}\n",
       "cfg.yaml:4: experiments[0]: give exactly one of 'offsets_m'"},
      {head + "  - name: e\n    type: xy\n    offsets_m: {+X+Z: [0.5]}\n",
       "cfg.yaml:6: experiments[0].offsets_m: unknown key '+X+Z'"},
      {head + "  - {name: e, type: spiral}\n",
       "cfg.yaml:4: experiments[0].type: unknown experiment type 'spiral'"},
      {head + "  - {name: e, type: yaw, yaw_deg: [1], k_values: [3]}\n",
       "cfg.yaml:4: experiments[0]: unknown key 'k_values' for an experiment of type yaw"},
      {head + "  - {name: e, type: yaw, yaw_deg: [1]}\n  - {name: e, type: yaw, yaw_deg: [2]}\n",
       "cfg.yaml:5: experiments[1].name: experiment name 'e' is used twice (first at line 4)"},
      {head + "  - {name: e, type: yaw, yaw_deg: [1], pose: {yaw_deg: 3}}\n",
       "cfg.yaml:4: experiments[0].pose.yaw_deg: this experiment varies yaw_deg"},
      {head + "  - {name: e, type: basin, levels: {yaw_deg: [0, 200]}}\n",
       "cfg.yaml:4: experiments[0].levels.yaw_deg: levels must be in [0, 180] degrees, got 200"},
      {head + "  - {name: e, type: random, yaw_deg: 190}\n",
       "cfg.yaml:4: experiments[0].yaw_deg: expected a number in [0, 180] degrees, got 190"},
      {head + "  - {name: e, type: random, translation_m: -1}\n",
       "cfg.yaml:4: experiments[0].translation_m: expected a number in [0, 1e+06] metres, got -1"},
      {head + "  - {name: e, type: random, roll_pitch_deg: 91}\n",
       "cfg.yaml:4: experiments[0].roll_pitch_deg: expected a number in [0, 90] degrees"},
      {head + "  - {name: e, type: random, up_axis: w}\n",
       "cfg.yaml:4: experiments[0].up_axis: expected x, y or z, got 'w'"},
      {head + "  - {name: e, type: random, pivot: corner}\n",
       "cfg.yaml:4: experiments[0].pivot: expected landmark, centroid or origin, got 'corner'"},
      {head + "  - {name: e, type: random, samples: 0}\n", "cfg.yaml:4: experiments[0].samples"},
      {head + "  - {name: e, type: random, levels: {yaw_deg: [1]}}\n",
       "cfg.yaml:4: experiments[0]: unknown key 'levels' for an experiment of type random"},
      {"source: {map: m.txt, frames: [120, 5]}\ntarget: b.txt\nexperiments: []\n",
       "cfg.yaml:1: source.frames: first frame id 120 > last frame id 5"},
      {"source: {map: m.txt, retriangulate: true}\ntarget: b.txt\nexperiments: []\n",
       "cfg.yaml:1: source.retriangulate: only applies to a frame window"},
      {"source: a.txt\ntarget: b.txt\nexperiments: []\n",
       "cfg.yaml:3: experiments: expected a non-empty list of experiments"},
      {"source: a.txt\ntarget: [b.txt\nexperiments: []\n", "cfg.yaml:3: YAML syntax error"},
      {"source: ${HOME}/a.txt\ntarget: b.txt\nexperiments: []\n",
       "cfg.yaml:1: source: unknown variable '${HOME}'"},
      {"", "cfg.yaml: empty config"},
  };
  for (const Bad& b : cases) {
    const std::string what = error_of(b.yaml);
    EXPECT_EQ(what.rfind(b.message, 0), 0u)
        << "got:      " << what << "\nexpected: " << b.message << "...\nfor:\n"
        << b.yaml;
  }
}

TEST(ExperimentConfig, LoadReportsAMissingFileAndUsesItsNameInErrors) {
  EXPECT_THROW(load_experiment_config("/nonexistent/cfg.yaml"), IoError);
  const auto dir =
      std::filesystem::temp_directory_path() / ("lmalign_cfg_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "mine.yaml").string();
  std::ofstream(path)
      << "source: a.txt\ntarget: b.txt\nexperiments:\n  - {name: e, type: yaw, yaw_deg: 5}\n";
  try {
    load_experiment_config(path);
    FAIL() << "expected ParseError";
  } catch (const ParseError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ":4: experiments[0].yaw_deg: expected a list of numbers");
  }
  std::ofstream(path) << kMinimal;
  const ExperimentConfig c = load_experiment_config(path);
  EXPECT_EQ(c.name, "mine");
  EXPECT_EQ(c.source.path, (dir / "a.txt").lexically_normal().string());
  std::filesystem::remove_all(dir);
}

TEST(ExperimentConfig, ResolvedConfigReadsBackToTheSameCases) {
  const ExperimentConfig c = parse(R"(source: a.txt
target: {map: m.txt, frames: [0, 119], retriangulate: true, min_parallax_deg: 3}
ground_truth: identity
strategies: [observations, base]
k: 7
max_iterations: 80
max_distance_m: 0.5
covariance_norm: frobenius
success: {rotation_deg: 3, translation_m: 0.05, score_m2: 0.01}
seed: 99
plot_case: t1/k=3
experiments:
  - {name: t1, type: k, k_values: [1, 3], pose: {x_m: 0.1, yaw_deg: 22.5}}
  - {name: t2, type: yaw, yaw_deg: [0, 10], k: 3, strategies: [base]}
  - {name: t3, type: xy, offsets_m: {-X+Y: [0.25, 0.9], +X-Y: [0.5]}, pose: {z_m: 0.2}}
  - {name: t3e, type: xy, escalate: {start_m: 0.2, step_m: 0.1, max_m: 0.5, stop: all}, quadrants: [-X-Y]}
  - {name: t4, type: xy_yaw, offset_m: 0.4, yaw_deg: [10, -10], quadrants: [+X+Y, -X-Y]}
  - {name: p, type: poses, poses: [{x_m: 1}, {roll_deg: 5, pitch_deg: -5}]}
  - {name: b, type: basin, levels: {yaw_deg: [0, 45]}, samples: 3, yaw_pivot: origin, translation_directions: xyz}
  - {name: r, type: random, samples: 4, seed: 5, yaw_deg: 90, translation_m: 10, roll_pitch_deg: 2, pivot: origin, up_axis: y}
)");
  const std::string yaml = resolved_config_yaml(c);
  const ExperimentConfig r = parse_experiment_config(yaml, "resolved.yaml", "/elsewhere");
  EXPECT_EQ(r.source.path, c.source.path);
  EXPECT_EQ(r.target.path, c.target.path);
  EXPECT_TRUE(r.target.retriangulate);
  EXPECT_EQ(r.target.min_parallax_deg, 3.0);
  EXPECT_EQ(r.ground_truth.kind, GroundTruthSpec::Kind::kIdentity);
  EXPECT_EQ(r.strategies, c.strategies);
  EXPECT_EQ(r.k, 7);
  EXPECT_EQ(r.max_iterations, 80);
  EXPECT_EQ(r.max_distance_m, 0.5);
  EXPECT_EQ(r.covariance_norm, CovarianceNorm::kFrobenius);
  EXPECT_EQ(r.success.rotation_deg, 3.0);
  EXPECT_EQ(r.success.translation_m, 0.05);
  EXPECT_EQ(r.success.score_m2, 0.01);
  EXPECT_EQ(r.seed, 99u);
  EXPECT_EQ(r.plot_case, "t1/k=3");
  EXPECT_TRUE(r.experiments[3].escalation.stop_when_all_fail);
  const RandomStartSpec& rs = r.experiments[7].random;
  EXPECT_EQ(r.experiments[7].type, ExperimentType::kRandom);
  EXPECT_EQ(rs.samples, 4);
  EXPECT_EQ(rs.seed, 5u);
  EXPECT_EQ(rs.yaw_deg, 90.0);
  EXPECT_EQ(rs.translation_m, 10.0);
  EXPECT_EQ(rs.roll_pitch_deg, 2.0);
  EXPECT_EQ(rs.pivot, YawPivot::kOrigin);
  EXPECT_EQ(rs.up_axis, CoordinateAxis::kY);
  const std::vector<Case> a = expand_cases(c), b = expand_cases(r);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].id(), b[i].id());
    EXPECT_EQ(a[i].k, b[i].k);
    EXPECT_EQ(a[i].strategies, b[i].strategies);
    EXPECT_TRUE(a[i].displacement == b[i].displacement) << a[i].id();
    EXPECT_TRUE(a[i].D.isApprox(b[i].D, 0.0)) << a[i].id();
  }
  // And again: the resolved form is a fixed point (apart from its first line, naming the file).
  const auto body = [](const std::string& s) { return s.substr(s.find('\n')); };
  EXPECT_EQ(body(resolved_config_yaml(r)), body(yaml));
}

TEST(ExperimentConfig, SelectExperimentsKeepsConfigOrderAndRejectsUnknownNames) {
  ExperimentConfig c = parse(R"(source: a.txt
target: b.txt
experiments:
  - {name: one, type: yaw, yaw_deg: [1]}
  - {name: two, type: yaw, yaw_deg: [2]}
  - {name: three, type: yaw, yaw_deg: [3]}
)");
  ExperimentConfig d = c;
  select_experiments(d, {"three", "one"});
  ASSERT_EQ(d.experiments.size(), 2u);
  EXPECT_EQ(d.experiments[0].name, "one");
  EXPECT_EQ(d.experiments[1].name, "three");
  try {
    select_experiments(c, {"four"});
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'four'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("one, two, three"), std::string::npos);
  }
}

// --- the schema as one table: scale, the nearest key, the table itself, the project's configs

const std::string kSchemaHead = "source: a.txt\ntarget: b.txt\nstrategies: [base, observations]\n";
const std::string kYawExperiment = "experiments: [{name: e, type: yaw, yaw_deg: [0]}]\n";

TEST(ExperimentSchema, ScaleIsGivenPerRunOrPerStrategyAndReachesTheRequest) {
  const ExperimentConfig none = parse(kSchemaHead + kYawExperiment);
  EXPECT_EQ(none.scale, ScaleMode::kAuto);
  EXPECT_EQ(run_request(none, "base", 5).scale, ScaleMode::kAuto);

  const ExperimentConfig all = parse(kSchemaHead + "scale: free\n" + kYawExperiment);
  EXPECT_EQ(run_request(all, "base", 5).scale, ScaleMode::kFree);
  EXPECT_EQ(run_request(all, "observations", 5).scale, ScaleMode::kFree);

  const ExperimentConfig each =
      parse(kSchemaHead + "scale: {observations: fixed, base: free}\n" + kYawExperiment);
  EXPECT_EQ(run_request(each, "base", 5).scale, ScaleMode::kFree);
  EXPECT_EQ(run_request(each, "observations", 5).scale, ScaleMode::kFixed);
  EXPECT_EQ(run_request(each, "covariance", 5).scale, ScaleMode::kAuto);

  // The resolved config keeps it.
  for (const ExperimentConfig* c : {&all, &each}) {
    const ExperimentConfig r = parse(resolved_config_yaml(*c));
    for (const char* s : {"base", "observations", "covariance"}) {
      EXPECT_EQ(r.scale_of(s), c->scale_of(s)) << s;
    }
  }

  const std::vector<std::pair<std::string, std::string>> refused = {
      {"scale: metric", "cfg.yaml:4: scale: expected auto, free or fixed, got 'metric'"},
      {"scale: {bse: free}", "cfg.yaml:4: scale: unknown strategy 'bse' (nearest: 'base')"},
      {"scale: {base: free, base: fixed}",
       "cfg.yaml:4: scale.base: strategy 'base' is given twice"},
      {"scale: [free]", "cfg.yaml:4: scale: expected auto, free or fixed, or a mapping"}};
  for (const auto& [line, message] : refused) {
    const std::string e = error_of(kSchemaHead + line + "\n" + kYawExperiment);
    EXPECT_EQ(e.rfind(message, 0), 0u) << e;
  }
}

TEST(ExperimentSchema, AnUnknownKeyNamesTheNearestKnownOne) {
  const std::string e = error_of(kSchemaHead + "strategis: [base]\n" + kYawExperiment);
  EXPECT_EQ(e.rfind("cfg.yaml:4: unknown key 'strategis' (expected one of: description", 0), 0u)
      << e;
  EXPECT_NE(e.find("; nearest: 'strategies')"), std::string::npos) << e;
  const std::string x =
      error_of(kSchemaHead + "experiments: [{name: e, type: random, pivto: origin}]\n");
  EXPECT_NE(x.find("unknown key 'pivto' for an experiment of type random"), std::string::npos);
  EXPECT_NE(x.find("nearest: 'pivot'"), std::string::npos) << x;
  // Far from every key: no nearest.
  EXPECT_EQ(error_of(kSchemaHead + "zzzzzzzz: 1\n" + kYawExperiment).find("nearest"),
            std::string::npos);
}

TEST(ExperimentSchema, EveryKeyOfTheTableIsDocumentedAndUnique) {
  std::set<std::string> seen;
  for (const ExperimentConfigKey& k : experiment_config_schema()) {
    EXPECT_FALSE(k.doc.empty()) << k.key;
    EXPECT_FALSE(k.value.empty()) << k.key;
    EXPECT_FALSE(k.bound.empty()) << k.key;
    // A key appears once per section and experiment type.
    EXPECT_TRUE(seen.insert(k.section + "/" + k.types + "/" + k.key).second) << k.key;
  }
  // The defaults shown are the structs' own.
  const auto value_of = [](const std::string& section, const std::string& key) {
    for (const ExperimentConfigKey& k : experiment_config_schema()) {
      if (k.section == section && k.key == key) return k.value;
    }
    return std::string("missing");
  };
  EXPECT_EQ(value_of("", "k"), "5");
  EXPECT_EQ(value_of("success", "score_m2"), "0.0037");
  EXPECT_EQ(value_of("experiments[].escalate", "stop"), "any");
  EXPECT_EQ(value_of("", "covariance_norm"), "spectral");
}

TEST(ExperimentSchema, TheProjectsConfigsParseAndResolveToThemselves) {
  const std::filesystem::path root = std::filesystem::path(__FILE__).parent_path() / "../..";
  // (bench/accuracy.yaml is the benchmark's own file: bench/run_accuracy.py writes experiment
  // configs from it.)
  std::vector<std::filesystem::path> files;
  for (const auto& f : std::filesystem::directory_iterator(root / "configs")) {
    // configs/merge_*.yaml are merge manifests (docs/merge.md), not experiment configs.
    const std::string name = f.path().filename().string();
    if (f.path().extension() == ".yaml" && name.rfind("merge_", 0) != 0) files.push_back(f.path());
  }
  ASSERT_GE(files.size(), 5u);
  ConfigLoadOptions o;
  o.data_dir = "/data";
  for (const auto& f : files) {
    SCOPED_TRACE(f.string());
    const ExperimentConfig c = load_experiment_config(f.string(), o);
    const std::string yaml = resolved_config_yaml(c);
    const ExperimentConfig r = parse_experiment_config(yaml, "resolved.yaml", "/elsewhere", o);
    const auto body = [](const std::string& text) { return text.substr(text.find('\n')); };
    EXPECT_EQ(body(resolved_config_yaml(r)), body(yaml));
    const Points3 points = test::room_points(50, 1);
    const std::vector<Case> a = expand_cases(c, points), b = expand_cases(r, points);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].id(), b[i].id());
      EXPECT_TRUE(a[i].D.isApprox(b[i].D, 0.0)) << a[i].id();
    }
  }
}

}  // namespace
}  // namespace lmalign
