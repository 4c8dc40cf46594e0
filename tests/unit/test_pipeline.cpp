// The registration engine (registration/pipeline.hpp, seams.hpp, settings.hpp): the stage
// registry and its refusals (unknown stages, stages that do not fit, unknown settings, values
// out of bounds), the settings table's text forms, and pipelines composed from stages that no
// preset combines, against a known transform on a seeded synthetic room; determinism over
// thread counts.
#include <omp.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "(no exception)";
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// ------------------------------------------------------------------------------------------
// The settings table
// ------------------------------------------------------------------------------------------

Settings small_table() {
  return Settings(
      {int_setting("match.k", "k", 5, SettingBound::closed(1, 4096), "count", "k"),
       real_setting("schedule.max_distance_m", "d", std::numeric_limits<double>::infinity(),
                    SettingBound::above_or_inf(0.0), "m", "d"),
       real_setting("kernel.scale_ratio", "r", 0.5, SettingBound::at_least(0.0), "1", "r"),
       choice_setting("kernel.confidence", "c", "uniform", {"uniform", "observations"}, "c"),
       reals_setting(
           "schedule.levels_m", "l", {1.0, 0.5},
           [] {
             SettingBound b = SettingBound::above_or_inf(0.0);
             b.min_size = 1;
             b.non_increasing = true;
             return b;
           }(),
           "m", "l"),
       bool_setting("match.reuse_neighbours", "u", true, "u")});
}

TEST(Settings, ValuesAreParsedCheckedAndPrintedBack) {
  Settings s = small_table();
  s.set_assignment("match.k=7");
  s.set_text("schedule.max_distance_m", "inf");
  s.set_text("kernel.confidence", "observations");
  s.set_text("schedule.levels_m", "[inf, 0.25,0.1]");
  s.set_text("match.reuse_neighbours", "false");
  EXPECT_EQ(s.integer("match.k"), 7);
  EXPECT_TRUE(std::isinf(s.real("schedule.max_distance_m")));
  EXPECT_EQ(s.choice("kernel.confidence"), "observations");
  EXPECT_EQ(s.reals("schedule.levels_m").size(), 3u);
  EXPECT_FALSE(s.boolean("match.reuse_neighbours"));
  EXPECT_TRUE(s.is_set("match.k"));
  EXPECT_FALSE(s.is_set("kernel.scale_ratio"));
  // An integer is accepted for a real setting.
  s.set("kernel.scale_ratio", 2LL);
  EXPECT_EQ(s.real("kernel.scale_ratio"), 2.0);
  EXPECT_EQ(s.canonical_text(),
            "match.k=7\nschedule.max_distance_m=inf\nkernel.scale_ratio=2\n"
            "kernel.confidence=observations\nschedule.levels_m=[inf, 0.25, 0.1]\n"
            "match.reuse_neighbours=false\n");
}

TEST(Settings, AValueOutsideItsBoundNamesTheKeyTheValueAndTheBound) {
  Settings s = small_table();
  EXPECT_EQ(message_of([&] { s.set_text("match.k", "0"); }),
            "match.k = 0 is outside its bound [1, 4096]");
  EXPECT_EQ(message_of([&] { s.set_text("schedule.max_distance_m", "-1"); }),
            "schedule.max_distance_m = -1 is outside its bound > 0 or inf");
  EXPECT_EQ(message_of([&] { s.set_text("kernel.scale_ratio", "inf"); }),
            "kernel.scale_ratio = inf is outside its bound >= 0");
  EXPECT_EQ(message_of([&] { s.set_text("kernel.confidence", "weights"); }),
            "kernel.confidence = 'weights' is not one of uniform, observations");
  const std::string order = message_of([&] { s.set_text("schedule.levels_m", "0.1, 0.5"); });
  EXPECT_TRUE(contains(order, "schedule.levels_m = [0.1, 0.5] is outside its bound")) << order;
  EXPECT_TRUE(contains(order, "non-increasing")) << order;
  EXPECT_TRUE(contains(message_of([&] { s.set_text("match.k", "five"); }), "match.k = 'five'"));
  // Nothing changed.
  EXPECT_EQ(s.integer("match.k"), 5);
}

TEST(Settings, AnUnknownKeyNamesTheNearestKnownOne) {
  Settings s = small_table();
  EXPECT_EQ(message_of([&] { s.set_text("match.kk", "3"); }),
            "unknown setting 'match.kk' (nearest: 'match.k')");
  EXPECT_EQ(message_of([&] { s.set_text("k", "3"); }), "unknown setting 'k' (nearest: 'match.k')");
  EXPECT_EQ(message_of([&] { s.set_text("schedule.levels", "1"); }),
            "unknown setting 'schedule.levels' (nearest: 'schedule.levels_m')");
  EXPECT_EQ(message_of([&] { s.set_text("completely.different", "1"); }),
            "unknown setting 'completely.different'");
  EXPECT_TRUE(contains(message_of([&] { s.set_assignment("match.k"); }), "expected KEY=VALUE"));
}

// ------------------------------------------------------------------------------------------
// Building pipelines
// ------------------------------------------------------------------------------------------

TEST(Pipeline, AnUnknownStageIsRefusedNamingTheSeamAndTheKnownStages) {
  PipelineSpec spec;
  spec.matcher = "nearst";
  const std::string m = message_of([&] { Pipeline p(spec); });
  EXPECT_TRUE(contains(m, "unknown matcher stage 'nearst'")) << m;
  EXPECT_TRUE(contains(m, "nearest, weighted_knn, mahalanobis_gate")) << m;
}

TEST(Pipeline, StagesThatDoNotFitTogetherAreRefused) {
  PipelineSpec spec;
  spec.estimator = "p2d_step";  // needs pairs with covariances; "nearest" gives points
  EXPECT_TRUE(
      contains(message_of([&] { Pipeline p(spec); }), "needs pairs with their covariances"));
  PipelineSpec gated;
  gated.matcher = "mahalanobis_gate";
  gated.estimator = "p2d_step";
  gated.schedule = "sigma_anneal";
  gated.rejectors = {"mutual"};
  EXPECT_TRUE(contains(message_of([&] { Pipeline p(gated); }),
                       "the rejectors stage 'mutual' does not take the pairs with their "
                       "covariances of the matcher 'mahalanobis_gate'"));
  PipelineSpec twice;
  twice.rejectors = {"trim", "trim"};
  EXPECT_TRUE(contains(message_of([&] { Pipeline p(twice); }), "'trim' is listed twice"));
}

TEST(Pipeline, SettingsAreTheStagesOwnAndRefusedOtherwise) {
  PipelineSpec spec;
  spec.schedule = "distance_levels";
  spec.settings = {{"schedule.levels_m", std::vector<double>{0.5, 0.1}}};
  const Pipeline p(spec);
  EXPECT_EQ(p.settings().reals("schedule.levels_m").size(), 2u);
  EXPECT_FALSE(p.settings().has("match.k"));  // nearest has no k
  EXPECT_FALSE(p.needs_scales());
  EXPECT_FALSE(p.settings().has("scales.floor_m"));
  spec.settings = {{"schedule.max_distance_m", 1.0}};  // the "pcl" schedule's, not this one's
  EXPECT_TRUE(contains(message_of([&] { Pipeline q(spec); }),
                       "unknown setting 'schedule.max_distance_m' for 'custom'"));
  spec.settings = {{"schedule.max_iterations", 0LL}};
  EXPECT_EQ(message_of([&] { Pipeline q(spec); }),
            "schedule.max_iterations = 0 is outside its bound [1, 2147483647]");
}

// ------------------------------------------------------------------------------------------
// Pipelines no preset has, against a known transform
// ------------------------------------------------------------------------------------------

class ComposedPipelines : public ::testing::Test {
 protected:
  void SetUp() override {
    const Points3 room = test::room_points(1500, 7);
    map_ = test::map_from_points(room, 8);
    target_.emplace(map_);
    // The source: the same room moved by a known transform (and its covariances with it).
    T_true_ = pose_from_xyz_rpy_deg(0.3, -0.2, 0.05, 1.0, -2.0, 25.0);
    source_.positions = transform_points(T_true_.inverse(), map_.positions());
    source_.covariances_m2 = transform_covariances(T_true_.inverse(), map_.covariances_m2());
    source_.up = Vec3::UnitZ();
  }
  TransformError error_of(const Summary& s) const {
    return transform_error(s.registration.T_target_source, T_true_);
  }
  Map map_;
  std::optional<PreparedTarget> target_;
  SourceLandmarks source_;
  Isometry3 T_true_;
};

// The robust presets' loop after `initialiser`: nearest pairs, Cauchy IRLS, shrinking distance
// levels; hypotheses scored by consensus, the result judged by inliers.
PipelineSpec robust_loop(const std::string& initialiser) {
  PipelineSpec spec;
  spec.initialiser = initialiser;
  spec.kernel = "cauchy";
  spec.schedule = "distance_levels";
  spec.scorer = "consensus";
  spec.trust = "inliers";
  return spec;
}

// The adaptive default's stages (configs/presets/adaptive.yaml: the Mahalanobis gate, its Cauchy
// weight, the point-to-distribution step, the annealed gate, the gated score and verdict) after
// `initialiser`.
PipelineSpec adaptive_after(const std::string& initialiser) {
  PipelineSpec spec = find_preset("adaptive").spec;
  spec.initialiser = initialiser;
  return spec;
}

TEST_F(ComposedPipelines, TheAdaptiveSearchThenARobustPointToPointLoop) {
  // The adaptive default's yaw-vote search (it needs the scales), each hypothesis refined by the
  // robust presets' loop (nearest, Cauchy, Umeyama, shrinking distances) on every 4th landmark
  // and scored by consensus.
  const PipelineSpec spec = robust_loop("yaw_vote");
  target_->set_up_axis(Vec3::UnitZ());
  const Pipeline p(spec);
  EXPECT_TRUE(p.needs_scales());
  EXPECT_TRUE(p.settings().has("scales.floor_m"));
  const Summary s = p.run(source_.view(), *target_);
  EXPECT_EQ(s.initialisation.initialisation, "global");
  EXPECT_GT(s.initialisation.resolution_m, 0.0);
  ASSERT_GE(s.hypotheses.size(), 2u);
  EXPECT_EQ(s.registration.termination, TerminationReason::kTransform);
  EXPECT_LT(error_of(s).rotation_deg, 0.05);
  EXPECT_LT(error_of(s).translation_m, 1e-3);
  EXPECT_TRUE(s.verdict.trustworthy) << s.verdict.reason;
  EXPECT_TRUE(s.covariance.valid);
}

TEST_F(ComposedPipelines, TheRobustSearchWithTheFourDofEstimatorAndTrimming) {
  PipelineSpec spec = robust_loop("yaw_centroid");
  spec.rejectors = {"trim"};
  spec.settings = {{"reject.trim_ratio", 0.9},
                   {"init.yaw_hypotheses", 24LL},
                   {"estimate.dof", std::string("4")}};
  // Yaw only: the 4-DoF estimator keeps roll and pitch.
  T_true_ = pose_from_xyz_rpy_deg(0.3, -0.2, 0.05, 0.0, 0.0, 100.0);
  source_.positions = transform_points(T_true_.inverse(), map_.positions());
  const Summary s = Pipeline(spec).run(source_.view(), *target_);
  ASSERT_EQ(s.hypotheses.size(), 25u);  // the guess and 24 yaws
  EXPECT_GE(s.hypotheses.front().score, s.hypotheses.back().score);
  EXPECT_LT(error_of(s).rotation_deg, 0.05);
  EXPECT_LT(error_of(s).translation_m, 1e-3);
  EXPECT_TRUE(s.at_estimate.computed);
  EXPECT_LT(s.at_estimate.overlap_ratio, 1.0);  // the trim acted
  EXPECT_TRUE(s.verdict.trustworthy) << s.verdict.reason;
}

TEST_F(ComposedPipelines, ResultsDoNotDependOnTheThreadCount) {
  PipelineSpec spec = adaptive_after("yaw_vote");
  spec.settings = {{"score.samples", 256LL}};
  const Pipeline p(spec);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const Summary one = p.run(source_.view(), *target_);
  omp_set_num_threads(3);
  const Summary three = p.run(source_.view(), *target_);
  omp_set_num_threads(saved);
  EXPECT_TRUE(one.registration.T_target_source.matrix() ==
              three.registration.T_target_source.matrix());
  EXPECT_TRUE(one.covariance.covariance == three.covariance.covariance);
  EXPECT_EQ(one.verdict.reason, three.verdict.reason);
  EXPECT_EQ(one.registration.iterations, three.registration.iterations);
  EXPECT_LT(error_of(one).rotation_deg, 0.05);
}

// Each hypothesis is refined on the scorer's samples and scored on every landmark
// (score.every_landmark), and the answer, refined on every landmark, is scored there too: the
// best hypothesis' score is then the verdict's gated score, the denominator of every rival's
// share. On the samples alone (false) the scores are sums over 256 of the 1,500 landmarks.
TEST_F(ComposedPipelines, HypothesesAreScoredOnEveryLandmarkAndTheAnswerAmongThem) {
  PipelineSpec spec = adaptive_after("yaw_vote");
  spec.settings = {{"score.samples", 256LL}};
  const Summary every = Pipeline(spec).run(source_.view(), *target_);
  ASSERT_GE(every.hypotheses.size(), 2u);
  EXPECT_LT(error_of(every).rotation_deg, 0.05);
  EXPECT_GT(every.verdict.score, 0.0);
  EXPECT_DOUBLE_EQ(every.hypotheses.front().score, every.verdict.score);
  spec.settings.push_back({"score.every_landmark", false});
  const Summary sampled = Pipeline(spec).run(source_.view(), *target_);
  ASSERT_GE(sampled.hypotheses.size(), 2u);
  EXPECT_LT(sampled.hypotheses.front().score, 0.5 * sampled.verdict.score);
  EXPECT_LT(error_of(sampled).rotation_deg, 0.05);
}

TEST_F(ComposedPipelines, APriorIsRefusedByAnInitialiserThatUsesNone) {
  PipelineSpec spec;
  PipelineRequest r;
  r.prior = PriorSigma{2.0, 0.1};
  EXPECT_TRUE(contains(message_of([&] { Pipeline(spec).run(source_.view(), *target_, r); }),
                       "the initialiser 'guess' of 'custom' uses no prior"));
}

// A pipeline with the sigma_anneal schedule (and the gate and estimator it goes with), and
// `settings` on top of the defaults.
Pipeline sigma_pipeline(std::vector<std::pair<std::string, SettingValue>> settings = {}) {
  PipelineSpec spec;
  spec.matcher = "mahalanobis_gate";
  spec.estimator = "p2d_step";
  spec.schedule = "sigma_anneal";
  spec.settings = std::move(settings);
  return Pipeline(spec);
}

// Scales for the schedule's tests: a 1 cm covariance floor (the settle threshold is 1e-3 of it)
// and a source of radius 1 m centred at (0.5, 0, 0).
Scales centimetre_scales() {
  Scales scales;
  scales.floor_m = 0.01;
  scales.source.radius_m = 1.0;
  scales.source.centre_m = Vec3(0.5, 0.0, 0.0);
  return scales;
}

TEST(SigmaSchedule, ATwoCycleAtZeroUncertaintyEndsTheRunAsSettled) {
  // A final refinement (zero pose uncertainty): steps of 1 mm, well above the settle threshold
  // (1e-3 x the 1 cm floor), alternate back and forth: the second one ends the run (the two
  // together do not move the source's centre). Two steps the same way do not.
  const Pipeline p = sigma_pipeline();
  const Scales scales = centimetre_scales();
  RefineContext c;
  c.scales = &scales;
  const Schedule& schedule = p.schedule();
  const Pairs pairs;
  auto step_by = [](const Vec3& t_m) {
    Step s;
    s.increment.translation() = t_m;
    return s;
  };
  for (const bool back_and_forth : {true, false}) {
    LoopState loop;
    loop.phase = Phase::kFinal;
    const std::unique_ptr<StageState> state = schedule.begin(c, Hypothesis{}, &loop);
    const Vec3 t(0.001, 0.0, 0.0);
    EXPECT_EQ(schedule.after_step(c, state.get(), step_by(t), pairs, &loop),
              TerminationReason::kNotTerminated);
    const TerminationReason second =
        schedule.after_step(c, state.get(), step_by(back_and_forth ? Vec3(-t) : t), pairs, &loop);
    EXPECT_EQ(second,
              back_and_forth ? TerminationReason::kTransform : TerminationReason::kNotTerminated);
  }
  // While the pose uncertainty is above zero, a 2-cycle only shrinks it (the next level).
  LoopState loop;
  loop.phase = Phase::kHypothesis;
  Hypothesis h;
  h.start_sigma_m = 0.1;
  h.start_sigma_rad = 0.1;
  const std::unique_ptr<StageState> state = schedule.begin(c, h, &loop);
  EXPECT_EQ(schedule.after_step(c, state.get(), step_by(Vec3(0.05, 0, 0)), pairs, &loop),
            TerminationReason::kNotTerminated);
  EXPECT_EQ(schedule.after_step(c, state.get(), step_by(Vec3(-0.05, 0, 0)), pairs, &loop),
            TerminationReason::kNotTerminated);
}

TEST(SigmaSchedule, ALongerCycleAtZeroUncertaintyEndsTheRunAsSettled) {
  // Three steps of 1 mm at 120 degrees to one another bring the estimate back to where it was:
  // a 3-cycle (pairs that switch their target landmark and switch back), which the 2-cycle test
  // does not see (any two of the steps move the source's centre by 1 mm, well above the settle
  // threshold of 1e-3 x the 1 cm floor). The third step ends the run, converged, unless
  // schedule.cycle_length is 2; three steps that do not come back (a creep) never end it.
  const Scales scales = centimetre_scales();
  RefineContext c;
  c.scales = &scales;
  const Pairs pairs;
  const double s = 0.001;
  const std::vector<Vec3> cycle = {Vec3(s, 0, 0), Vec3(-0.5 * s, 0.866 * s, 0),
                                   Vec3(-0.5 * s, -0.866 * s, 0)};
  const std::vector<Vec3> creep = {Vec3(s, 0, 0), Vec3(0, s, 0), Vec3(s, 0, 0),
                                   Vec3(0, s, 0), Vec3(s, 0, 0), Vec3(0, s, 0)};
  auto run = [&](long long cycle_length, const std::vector<Vec3>& steps) {
    const Pipeline p = sigma_pipeline({{"schedule.cycle_length", cycle_length}});
    LoopState loop;
    loop.phase = Phase::kFinal;
    const std::unique_ptr<StageState> state = p.schedule().begin(c, Hypothesis{}, &loop);
    Isometry3 estimate = Isometry3::Identity();
    std::vector<TerminationReason> out;
    for (const Vec3& t_m : steps) {
      Step step;
      step.increment.translation() = t_m;
      estimate = step.increment * estimate;
      step.estimate.T_target_source = estimate;
      out.push_back(p.schedule().after_step(c, state.get(), step, pairs, &loop));
    }
    return out;
  };
  const std::vector<TerminationReason> cycled = run(8, cycle);
  ASSERT_EQ(cycled.size(), 3u);
  EXPECT_EQ(cycled[0], TerminationReason::kNotTerminated);
  EXPECT_EQ(cycled[1], TerminationReason::kNotTerminated);
  EXPECT_EQ(cycled[2], TerminationReason::kTransform);
  for (const TerminationReason r : run(2, cycle)) EXPECT_EQ(r, TerminationReason::kNotTerminated);
  for (const TerminationReason r : run(8, creep)) EXPECT_EQ(r, TerminationReason::kNotTerminated);
}

TEST_F(ComposedPipelines, AHypothesisCapsItsOwnRefinement) {
  // A search refines many candidates briefly (complete_search): Hypothesis::max_iterations and
  // max_iterations_per_level cap one refinement below the schedule's own budget.
  PipelineSpec spec = adaptive_after("guess");
  spec.scorer = "none";
  spec.trust = "none";
  const Pipeline p(spec);
  Scales scales;
  scales.source = estimate_data_scales(source_.positions, &source_.covariances_m2);
  scales.target = estimate_data_scales(target_->points(), &target_->covariances_m2());
  scales.floor_m = std::max(scales.source.floor_m, scales.target.floor_m);
  InitialiserReport init;
  RefineContext c;
  c.source = source_.view();
  c.target = &*target_;
  c.scales = &scales;
  c.init = &init;
  Hypothesis h;
  h.T_target_source = pose_from_xyz_rpy_deg(0.02, 0.0, 0.0, 0.0, 0.0, 1.0) * T_true_;
  h.start_sigma_m = 0.05;
  h.start_sigma_rad = 0.02;
  const Refinement free_run = p.refine(c, h, Phase::kHypothesis);
  ASSERT_GT(free_run.iterations, 3);
  h.max_iterations = 3;
  const Refinement capped = p.refine(c, h, Phase::kHypothesis);
  EXPECT_EQ(capped.iterations, 3);
  EXPECT_EQ(capped.termination, TerminationReason::kMaxIterations);
  h.max_iterations = 0;
  h.max_iterations_per_level = 1;
  const Refinement fast_levels = p.refine(c, h, Phase::kHypothesis);
  EXPECT_GE(fast_levels.loop.level, free_run.loop.level);
  EXPECT_LT(transform_error(free_run.T, T_true_).translation_m, 1e-3);
}

}  // namespace
}  // namespace lmalign
