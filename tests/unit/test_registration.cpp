#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <omp.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/score.hpp"
#include "support/align_preset.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

// Source = the first 2/3 of the target's landmarks, expressed in a frame moved by T_true^-1:
// the exact answer is T_true with a zero residual.
struct Scene {
  Map target;
  Points3 source;
  Isometry3 T_true;
};

Scene make_scene(const Isometry3& T_true, std::uint32_t seed = 31) {
  Scene s;
  const Points3 pts = test::room_points(3000, seed);
  s.target = test::map_from_points(pts, seed + 1);
  s.T_true = T_true;
  const Points3 sub(pts.begin(), pts.begin() + 2000);
  s.source = transform_points(T_true.inverse(), sub);
  return s;
}

/// The paper's strategy of a confidence (base, or its weighted kNN), as every front end runs it.
RegistrationResult paper(const Points3& source, const PreparedTarget& target, WeightKind weight,
                         const test::Ask& ask = {}) {
  return test::align_with(test::paper_preset(weight), source, target, ask).registration;
}

test::Ask with_k(int k) {
  test::Ask a;
  a.k = k;
  return a;
}

TEST(Registration, BaseIcpRecoversAKnownTransformExactly) {
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0.10, -0.08, 0.03, 2, -1, 6));
  const PreparedTarget target(s.target);
  const RegistrationResult r = paper(s.source, target, WeightKind::kUniform);
  const TransformError e = transform_error(r.T_target_source, s.T_true);
  EXPECT_LT(e.rotation_deg, 1e-6);
  EXPECT_LT(e.translation_m, 1e-8);
  EXPECT_TRUE(r.converged);
  EXPECT_NE(r.termination, TerminationReason::kMaxIterations);
  EXPECT_LT(r.final_score_m2, 1e-14);
  EXPECT_GT(r.initial_score_m2, 1e-4);
  EXPECT_EQ(r.num_correspondences, s.source.size());
}

TEST(Registration, WeightedStrategiesReachTheRightBasin) {
  // Weighted-kNN prefers a trusted neighbour over the exact one, so its optimum is biased; on
  // this dense scene the bias is small.
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0.10, -0.08, 0.03, 2, -1, 6));
  const PreparedTarget target(s.target);
  for (WeightKind st :
       {WeightKind::kCovariance, WeightKind::kObservations, WeightKind::kMeanDistance}) {
    const RegistrationResult r = paper(s.source, target, st, with_k(5));
    const TransformError e = transform_error(r.T_target_source, s.T_true);
    EXPECT_LT(e.rotation_deg, 1.0) << to_string(st);
    EXPECT_LT(e.translation_m, 0.03) << to_string(st);
    EXPECT_LT(r.final_score_m2, r.initial_score_m2) << to_string(st);
  }
}

TEST(Registration, WeightedWithKOneEqualsBase) {
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0.3, 0.2, -0.1, 5, 3, -20));
  const PreparedTarget target(s.target);
  const RegistrationResult base = paper(s.source, target, WeightKind::kUniform);
  for (WeightKind st :
       {WeightKind::kCovariance, WeightKind::kObservations, WeightKind::kMeanDistance}) {
    const RegistrationResult r = paper(s.source, target, st, with_k(1));
    EXPECT_EQ(r.iterations, base.iterations) << to_string(st);
    EXPECT_EQ(r.termination, base.termination) << to_string(st);
    EXPECT_TRUE(r.T_target_source.matrix() == base.T_target_source.matrix()) << to_string(st);
    EXPECT_EQ(r.final_score_m2, base.final_score_m2) << to_string(st);
  }
}

TEST(Registration, SameResultForAnyThreadCount) {
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0.3, 0.2, -0.1, 5, 3, -20));
  const PreparedTarget target(s.target);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const RegistrationResult one = paper(s.source, target, WeightKind::kObservations, with_k(5));
  omp_set_num_threads(3);
  const RegistrationResult three = paper(s.source, target, WeightKind::kObservations, with_k(5));
  omp_set_num_threads(saved);
  EXPECT_EQ(one.iterations, three.iterations);
  EXPECT_TRUE(one.T_target_source.matrix() == three.T_target_source.matrix());
  EXPECT_EQ(one.final_score_m2, three.final_score_m2);
}

TEST(Registration, HistoryMatchesTheScoreAndTheMse) {
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0.1, 0.0, 0.0, 0, 0, 4));
  const PreparedTarget target(s.target);
  test::Ask history;
  history.record_history = true;  // and the score at each iteration
  const RegistrationResult r = paper(s.source, target, WeightKind::kUniform, history);
  ASSERT_EQ(static_cast<int>(r.history.size()), r.iterations);
  ASSERT_GE(r.iterations, 2);
  for (int i = 0; i < r.iterations; ++i) EXPECT_EQ(r.history[i].iteration, i + 1);
  EXPECT_EQ(r.history.back().score_m2, r.final_score_m2);
  EXPECT_LT(r.history.back().mse_m2, r.history.front().mse_m2);
  // The first iteration's MSE is the score of the initial guess (base ICP: same nearest pairs).
  EXPECT_NEAR(r.history.front().mse_m2, r.initial_score_m2, 1e-15);
  // Without history_scores the score column is NaN (not computed).
  SourceView view;
  view.positions = &s.source;
  PipelineRequest without;
  without.record_history = true;
  without.history_scores = false;
  const RegistrationResult r2 =
      Pipeline(find_preset("base").spec).run(view, target, without).registration;
  EXPECT_TRUE(std::isnan(r2.history.front().score_m2));
  EXPECT_EQ(r2.iterations, r.iterations);
}

TEST(Registration, MaxIterationsIsReportedAndNotConverged) {
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0.3, 0.2, -0.1, 5, 3, -20));
  const PreparedTarget target(s.target);
  test::Ask two;
  two.max_iterations = 2;
  const RegistrationResult r = paper(s.source, target, WeightKind::kUniform, two);
  EXPECT_EQ(r.iterations, 2);
  EXPECT_EQ(r.termination, TerminationReason::kMaxIterations);
  EXPECT_FALSE(r.converged);
}

TEST(Registration, NoCorrespondencesKeepsTheInitialGuess) {
  const Scene s = make_scene(pose_from_xyz_rpy_deg(0, 0, 0, 0, 0, 0));
  const PreparedTarget target(s.target);
  test::Ask o;
  o.max_distance_m = 1e-9;
  o.initial_guess = pose_from_xyz_rpy_deg(5, 5, 5, 0, 0, 0);
  const Isometry3 init = *o.initial_guess;
  const RegistrationResult r = paper(s.source, target, WeightKind::kObservations, o);
  EXPECT_EQ(r.termination, TerminationReason::kNoCorrespondences);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_TRUE(r.T_target_source.matrix() == init.matrix());
  EXPECT_TRUE(std::isfinite(r.final_score_m2));
}

TEST(PaperSettings, ValuesOutsideTheirBoundsAreRefusedNamingTheKey) {
  const Scene s = make_scene(Isometry3::Identity());
  const PreparedTarget target(s.target);
  for (const char* bad : {"match.k=0", "schedule.max_distance_m=nan", "schedule.max_iterations=-1",
                          "fitness.max_range_m=-2"}) {
    const std::string key = std::string(bad).substr(0, std::string(bad).find('='));
    try {
      paper(s.source, target, WeightKind::kObservations, {{bad}});
      ADD_FAILURE() << bad << " accepted";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
  test::Ask bad;
  bad.initial_guess = Isometry3::Identity();
  (*bad.initial_guess)(0, 3) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(paper(s.source, target, WeightKind::kUniform, bad), InvalidArgument);
}

TEST(PreparedTarget, BarePointsHaveOnlyUniformWeights) {
  PreparedTarget t(test::room_points(10, 1));
  EXPECT_EQ(t.weights(WeightKind::kUniform).size(), 10u);
  EXPECT_THROW(t.weights(WeightKind::kObservations), InvalidArgument);
  EXPECT_THROW(t.set_weights(WeightKind::kObservations, std::vector<double>(9, 1.0)),
               InvalidArgument);
  t.set_weights(WeightKind::kObservations, std::vector<double>(10, 2.0));
  EXPECT_EQ(t.weights(WeightKind::kObservations)[3], 2.0);
}

TEST(WeightKind, Names) {
  for (WeightKind s : all_weight_kinds()) EXPECT_EQ(parse_weight_kind(to_string(s)), s);
  EXPECT_EQ(parse_weight_kind("none"), WeightKind::kUniform);
  EXPECT_THROW(parse_weight_kind("cov"), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
