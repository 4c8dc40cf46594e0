// The presets (registration/presets.hpp): the built-in files (configs/presets/*.yaml) read, one
// recommended, names and aliases unique; a user's preset file refused with the file, the line and
// what is wrong (an unknown stage named with the known ones, an unknown setting with the nearest
// known key, a value outside its bound); requests resolved into settings (k, limits, --set); and
// an experiment config's `settings:` read against each strategy's table.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <set>
#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/presets.hpp"

namespace lmalign {
namespace {

std::string parse_error_of(const std::string& yaml) {
  try {
    (void)parse_preset(yaml, "mine", "mine.yaml");
  } catch (const ParseError& e) {
    return e.what();
  }
  return "(no ParseError)";
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

const char* kGood =
    "doc: mine\n"
    "group: lmalign\n"
    "initialiser: guess\n"
    "matcher: nearest\n"
    "kernel: cauchy\n"
    "estimator: umeyama\n"
    "schedule: distance_levels\n"
    "trust: inliers\n";

TEST(Presets, BuiltInPresetsAreReadWithUniqueNamesAndOneDefault) {
  const std::vector<Preset>& all = presets();
  ASSERT_FALSE(all.empty());
  std::set<std::string> names;
  int recommended = 0;
  for (const Preset& p : all) {
    EXPECT_TRUE(names.insert(p.name).second) << p.name;
    for (const std::string& a : p.aliases) EXPECT_TRUE(names.insert(a).second) << a;
    EXPECT_FALSE(p.doc.empty()) << p.name;
    EXPECT_EQ(p.file, "configs/presets/" + p.name + ".yaml");
    recommended += p.recommended ? 1 : 0;
    // Every preset builds its pipeline and its settings are within their bounds.
    const Pipeline pipeline(p.spec);
    std::string why;
    EXPECT_TRUE(pipeline.settings().is_valid(&why)) << p.name << ": " << why;
  }
  EXPECT_EQ(recommended, 1);
  EXPECT_TRUE(recommended_preset().recommended);
  // The paper's four, in the paper's column order.
  EXPECT_EQ(preset_names("paper"),
            (std::vector<std::string>{"base", "covariance", "observations", "distance"}));
  // Aliases find their preset.
  EXPECT_EQ(find_preset("none").name, "base");
  EXPECT_EQ(find_preset("mean_distance").name, "distance");
  EXPECT_TRUE(find_preset("observations").uses_k());
  EXPECT_FALSE(find_preset("base").uses_k());
}

// Which presets depend on the landmark covariances, and which read a target confidence: a
// distribution matcher (adaptive) or a covariance confidence (covariance) use covariances; the
// observation weight is read by observations' matcher and robust_obs's kernel.
TEST(Presets, PipelinesSayWhatTheyWeighBy) {
  auto pipeline = [](const char* name) { return Pipeline(find_preset(name).spec); };
  EXPECT_FALSE(pipeline("base").uses_covariances());
  EXPECT_TRUE(pipeline("covariance").uses_covariances());
  EXPECT_FALSE(pipeline("observations").uses_covariances());
  EXPECT_FALSE(pipeline("robust_obs").uses_covariances());
  EXPECT_TRUE(pipeline("adaptive").uses_covariances());
  EXPECT_TRUE(pipeline("base").confidences().empty());
  EXPECT_EQ(pipeline("covariance").confidences(), std::vector<WeightKind>{WeightKind::kCovariance});
  EXPECT_EQ(pipeline("distance").confidences(), std::vector<WeightKind>{WeightKind::kMeanDistance});
  EXPECT_EQ(pipeline("robust_obs").confidences(),
            std::vector<WeightKind>{WeightKind::kObservations});
}

// A point cloud: landmarks without observations, with (assumed) isotropic covariances. The
// observation weight is 0 everywhere: a strategy that weighs by it aligns nothing and is refused
// with the reason; base ICP aligns it. With covariances_assumed, only the strategies that use
// covariances flag it (and say so at the end of their reason).
TEST(Presets, PointCloudsWithoutObservationsOrMeasuredCovariances) {
  Map cloud;
  for (int i = 0; i < 400; ++i) {
    Landmark l;
    l.id = i;
    l.p_world = Vec3(2.0 * std::sin(1.3 * i), 3.0 * std::cos(0.7 * i), 0.3 * (i % 7));
    l.cov_world_m2 = Mat3::Identity() * 1e-4;
    cloud.landmarks.push_back(l);
  }
  const PreparedTarget target(cloud);
  SourceLandmarks source = SourceLandmarks::from_map(cloud);
  AlignRequest request;
  request.covariances_assumed = true;
  Isometry3 guess = Isometry3::Identity();
  guess.translation() = Vec3(0.02, -0.01, 0.0);
  request.initial_guess = guess;
  const std::string note = "; covariances assumed from the landmark spacing";
  for (const char* name : {"observations", "distance", "robust_obs"}) {
    SCOPED_TRACE(name);
    const Summary s = align(find_preset(name), source.view(), target, request);
    EXPECT_FALSE(s.verdict.trustworthy);
    EXPECT_TRUE(contains(s.verdict.reason, "weight 0 (it has no observations: a point cloud)"))
        << s.verdict.reason;
    EXPECT_FALSE(s.covariances_assumed);
    EXPECT_FALSE(contains(s.verdict.reason, note)) << s.verdict.reason;
  }
  const Summary base = align(find_preset("base"), source.view(), target, request);
  EXPECT_TRUE(base.verdict.trustworthy) << base.verdict.reason;
  EXPECT_EQ(base.verdict.reason, "ok");
  EXPECT_FALSE(base.covariances_assumed);
  EXPECT_LT(base.registration.T_target_source.translation().norm(), 1e-9);
  const Summary cov = align(find_preset("covariance"), source.view(), target, request);
  EXPECT_TRUE(cov.covariances_assumed);
  EXPECT_TRUE(contains(cov.verdict.reason, note)) << cov.verdict.reason;
  EXPECT_TRUE(contains(to_json(cov), "\"covariances_assumed\":true")) << to_json(cov);
  request.covariances_assumed = false;
  const Summary measured = align(find_preset("covariance"), source.view(), target, request);
  EXPECT_FALSE(measured.covariances_assumed);
  EXPECT_FALSE(contains(measured.verdict.reason, note)) << measured.verdict.reason;
}

TEST(Presets, UnknownNamesNameTheNearestPreset) {
  try {
    (void)find_preset("robust_ob");
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_TRUE(contains(e.what(), "unknown strategy 'robust_ob' (nearest: 'robust_obs')"))
        << e.what();
  }
  try {
    (void)find_preset("cov");  // a prefix counts as near
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_TRUE(contains(e.what(), "(nearest: 'covariance')")) << e.what();
  }
  EXPECT_FALSE(is_preset_name("shrink"));
}

TEST(Presets, AFileIsRefusedWithItsLineAndWhatIsWrong) {
  const Preset p = parse_preset(kGood, "mine", "mine.yaml");
  EXPECT_EQ(p.spec.kernel, "cauchy");
  EXPECT_EQ(p.spec.matcher, "nearest");

  std::string e = parse_error_of(std::string(kGood) + "rejectors: [mutual, trim_typo]\n");
  EXPECT_TRUE(contains(e, "mine.yaml:9")) << e;
  EXPECT_TRUE(contains(e, "unknown rejectors stage 'trim_typo'")) << e;
  EXPECT_TRUE(contains(e, "known: ")) << e;

  std::string bad = kGood;
  bad.replace(bad.find("matcher: nearest"), 16, "matcher: nearst");
  e = parse_error_of(bad);
  EXPECT_TRUE(contains(e, "mine.yaml:4")) << e;
  EXPECT_TRUE(contains(e, "unknown matcher stage 'nearst'")) << e;

  e = parse_error_of(std::string(kGood) + "settings:\n  kernel.scale_mm: 0.1\n");
  EXPECT_TRUE(contains(e, "mine.yaml:10")) << e;
  EXPECT_TRUE(contains(e, "unknown setting 'kernel.scale_mm' (nearest: 'kernel.scale_m')")) << e;

  e = parse_error_of(std::string(kGood) + "settings:\n  kernel.scale_m: -1\n");
  EXPECT_TRUE(contains(e, "mine.yaml:10")) << e;
  EXPECT_TRUE(contains(e, "kernel.scale_m = -1 is outside")) << e;

  e = parse_error_of(std::string(kGood) + "colour: blue\n");
  EXPECT_TRUE(contains(e, "mine.yaml:9: unknown key 'colour'")) << e;

  e = parse_error_of("doc: x\ngroup: lmalign\ninitialiser: guess\n");
  EXPECT_TRUE(contains(e, "missing key 'matcher'")) << e;
}

TEST(Presets, APresetFileIsFoundByItsPath) {
  const std::string path = ::testing::TempDir() + "lmalign_preset_test_mine.yaml";
  {
    std::ofstream out(path);
    out << kGood << "settings:\n  kernel.confidence: uniform\n  schedule.levels_m: [inf, 0.5]\n";
  }
  const Preset p = find_preset(path);
  EXPECT_EQ(p.name, "lmalign_preset_test_mine");
  EXPECT_EQ(p.file, path);
  const Pipeline pipeline(p.spec);
  EXPECT_EQ(pipeline.settings().reals("schedule.levels_m").size(), 2u);
  EXPECT_THROW((void)find_preset(::testing::TempDir() + "no_such_preset.yaml"), IoError);
}

TEST(Presets, RequestsBecomeSettingsAndSettingsWin) {
  const Preset& base = find_preset("observations");
  AlignRequest r;
  r.k = 7;
  r.max_iterations = 20;
  Pipeline p(resolve_spec(base, r));
  EXPECT_EQ(p.settings().integer("match.k"), 7);
  EXPECT_EQ(p.settings().integer("schedule.max_iterations"), 20);
  // --set wins over k.
  r.settings = {{"match.k", SettingValue(3LL)}};
  p = Pipeline(resolve_spec(base, r));
  EXPECT_EQ(p.settings().integer("match.k"), 3);
  // Unknown keys and values out of bounds are refused.
  r.settings = {{"match.kk", SettingValue(3LL)}};
  EXPECT_THROW((void)Pipeline(resolve_spec(base, r)), InvalidArgument);
  r.settings = {{"match.k", SettingValue(0LL)}};
  EXPECT_THROW((void)Pipeline(resolve_spec(base, r)), InvalidArgument);
}

TEST(Presets, AnExperimentsSettingsAreReadAgainstEachStrategysTable) {
  const std::string head =
      "source: a.txt\ntarget: b.txt\nstrategies: [base, robust_obs]\n"
      "experiments: [{name: yaws, type: yaw, yaw_deg: [0, 10]}]\n";
  const ExperimentConfig c = parse_experiment_config(
      head +
          "settings:\n  robust_obs:\n    kernel.scale_m: 0.03\n    schedule.levels_m: [inf, "
          "0.5, 0.1]\n",
      "cfg.yaml", "/base", {});
  ASSERT_EQ(c.settings.size(), 1u);
  EXPECT_EQ(c.settings[0].first, "robust_obs");
  ASSERT_EQ(c.settings[0].second.size(), 2u);
  EXPECT_EQ(std::get<double>(c.settings[0].second[0].second), 0.03);

  auto error_of = [&](const std::string& settings) {
    try {
      (void)parse_experiment_config(head + settings, "cfg.yaml", "/base", {});
    } catch (const ParseError& e) {
      return std::string(e.what());
    }
    return std::string("(no ParseError)");
  };
  std::string e = error_of("settings:\n  robust_obs:\n    kernel.scale: 0.03\n");
  EXPECT_TRUE(contains(e, "cfg.yaml:7")) << e;
  EXPECT_TRUE(contains(e, "unknown setting 'kernel.scale' (nearest: 'kernel.scale_m')")) << e;
  e = error_of("settings:\n  robust_obs:\n    kernel.scale_m: -2\n");
  EXPECT_TRUE(contains(e, "cfg.yaml:7")) << e;
  EXPECT_TRUE(contains(e, "kernel.scale_m = -2 is outside")) << e;
  e = error_of("settings:\n  robust_ob:\n    kernel.scale_m: 1\n");
  EXPECT_TRUE(contains(e, "cfg.yaml:6")) << e;
}

}  // namespace
}  // namespace lmalign
