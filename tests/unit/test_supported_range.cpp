// The supported range (core/supported_range.hpp, docs/robustness.md "Supported range"): one
// check for every alignment. Landmarks beyond it are left out of every strategy, counted and
// named in the trust reason, and the result is the one without them; guesses and priors beyond
// it are one-line errors; far landmarks within it do not derail the adaptive default; an
// exception in a parallel loop reaches the caller.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"
#include "lmalign/registration/supported_landmarks.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "(no InvalidArgument)";
}

/// A room (test::room_points) as target, with covariances, weights and frames (a Map), and the
/// source: the same landmarks moved by T_true^-1, so that p_target = T_true * p_source.
struct Pair {
  Map target;
  SourceLandmarks source;
  Isometry3 T_true;
};

Pair make_pair(std::size_t n, std::uint32_t seed) {
  Pair p;
  p.target = test::map_from_points(test::room_points(n, seed), seed + 1);
  p.T_true = pose_from_xyz_rpy_deg(0.3, -0.2, 0.05, 1.0, -0.5, 25.0);
  const Map source = transform_map(p.target, p.T_true.inverse());
  p.source.positions = source.positions();
  p.source.covariances_m2 = source.covariances_m2();
  p.source.up = p.T_true.linear().transpose() * Vec3::UnitZ();
  return p;
}

/// Runs the preset `strategy` (the recommended one if empty) as every front end does.
Summary run(const SourceLandmarks& source, const PreparedTarget& target,
            const std::string& strategy = "", const AlignRequest& request = {}) {
  return align(strategy.empty() ? recommended_preset() : find_preset(strategy), source.view(),
               target, request);
}

PreparedTarget prepared(const Map& map) {
  PreparedTarget t(map);
  t.set_up_axis(Vec3::UnitZ());
  return t;
}

TEST(SupportedRange, PredicateBoundsAndMessages) {
  EXPECT_TRUE(within_supported_range(Vec3(kMaxCoordinateM, -kMaxCoordinateM, 0)));
  EXPECT_FALSE(within_supported_range(Vec3(0, std::nextafter(kMaxCoordinateM, kInf), 0)));
  EXPECT_FALSE(within_supported_range(Vec3(0, 0, kNaN)));
  EXPECT_FALSE(within_supported_range(Vec3(-kInf, 0, 0)));
  EXPECT_EQ(beyond_supported_range({Vec3(1, 2, 3), Vec3(1e300, 0, 0), Vec3(0, 0, 2e15)}),
            (std::vector<std::size_t>{1, 2}));
  EXPECT_EQ(message_of([] {
              check_supported_translation("--displace 1e308,0,0,0,0,0", Vec3(1e308, 0, 0));
            }),
            "--displace 1e308,0,0,0,0,0: translation (1e+308, 0, 0) m is beyond the supported "
            "range (|coordinate| <= 1e+15 m)");
  EXPECT_NO_THROW(check_supported_translation("t", Vec3(kMaxCoordinateM, 0, 0)));
  EXPECT_EQ(message_of([] { check_supported_magnitude("roll", -1e20, kMaxAngleDeg, "degrees"); }),
            "roll: -1e+20 degrees is beyond the supported range (|value| <= 1e+15 degrees)");
  EXPECT_THROW(check_supported_magnitude("x", kNaN, 1.0, "m"), InvalidArgument);
  EXPECT_EQ(left_out_message(0, 0), "");
  EXPECT_EQ(left_out_message(1, 0),
            "1 source landmark beyond the supported range (|coordinate| > 1e+15 m) left out");
  EXPECT_EQ(left_out_message(2, 1),
            "2 source landmarks and 1 target landmark beyond the supported range (|coordinate| > "
            "1e+15 m) left out");
}

TEST(SupportedRange, EveryStrategyLeavesOutLandmarksBeyondItAndAlignsTheRestAsWithoutThem) {
  // A stereo landmark at near-zero disparity: 1e300 m in the source, 1e20 m and 1e16 m in the
  // target, in otherwise good maps. Every strategy's result is bit for bit the one on the maps
  // without them, counted and named in the trust reason.
  const Pair p = make_pair(150, 51);
  SourceLandmarks far_source = p.source;
  far_source.positions[7] = Vec3(1e300, 0.5, 0.5);
  Map far_target = p.target;
  far_target.landmarks[3].p_world = Vec3(0.5, -1e20, 0.5);
  far_target.landmarks[100].p_world.z() = 1e16;
  SourceLandmarks near_source = p.source;
  near_source.positions.erase(near_source.positions.begin() + 7);
  near_source.covariances_m2.erase(near_source.covariances_m2.begin() + 7);
  Map near_target = p.target;
  near_target.landmarks.erase(near_target.landmarks.begin() + 100);
  near_target.landmarks.erase(near_target.landmarks.begin() + 3);
  const PreparedTarget far_prepared = prepared(far_target);
  const PreparedTarget near_prepared = prepared(near_target);
  for (const std::string& s : preset_names()) {
    const Summary far = run(far_source, far_prepared, s);
    const Summary near = run(near_source, near_prepared, s);
    EXPECT_EQ(far.source_left_out, 1u) << s;
    EXPECT_EQ(far.target_left_out, 2u) << s;
    EXPECT_EQ(near.source_left_out + near.target_left_out, 0u) << s;
    EXPECT_TRUE(far.registration.T_target_source.isApprox(near.registration.T_target_source, 0.0))
        << s;
    EXPECT_EQ(far.verdict.trustworthy, near.verdict.trustworthy) << s;
    EXPECT_EQ(far.verdict.reason, near.verdict.reason + "; " + left_out_message(1, 2)) << s;
  }
}

TEST(SupportedRange, KeptTargetCopiesWeightsCovariancesAndUpAxis) {
  Map map = test::map_from_points(test::room_points(50, 52), 53);
  map.landmarks[10].p_world.x() = -1e18;
  const PreparedTarget t = prepared(map);
  SourceLandmarks s;
  s.positions = {Vec3(1, 2, 3), Vec3(1e99, 0, 0), Vec3(0, 1, 0)};
  s.covariances_m2 = {Mat3::Identity(), 2.0 * Mat3::Identity(), 3.0 * Mat3::Identity()};
  s.up = Vec3::UnitY();
  const SupportedLandmarks kept = keep_supported_landmarks(s.view(), t);
  ASSERT_TRUE(kept.source && kept.target);
  EXPECT_EQ(kept.source->positions, (Points3{Vec3(1, 2, 3), Vec3(0, 1, 0)}));
  EXPECT_EQ(kept.source->covariances_m2[1], 3.0 * Mat3::Identity());
  EXPECT_EQ(kept.source->up, s.up);
  ASSERT_EQ(kept.target->size(), 49u);
  EXPECT_EQ(kept.target->points()[10], t.points()[11]);
  for (WeightKind kind : {WeightKind::kUniform, WeightKind::kCovariance, WeightKind::kObservations,
                          WeightKind::kMeanDistance}) {
    EXPECT_EQ(kept.target->weights(kind)[10], t.weights(kind)[11]) << to_string(kind);
    EXPECT_EQ(kept.target->weights(kind)[9], t.weights(kind)[9]) << to_string(kind);
  }
  EXPECT_EQ(kept.target->covariances_m2()[10], t.covariances_m2()[11]);
  EXPECT_EQ(kept.target->up_axis(), t.up_axis());
  // Nothing beyond: no copies.
  const SourceLandmarks near{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {}, {}};
  const SupportedLandmarks none = keep_supported_landmarks(
      near.view(), prepared(test::map_from_points(test::room_points(20, 54), 55)));
  EXPECT_FALSE(none.source || none.target);
}

TEST(SupportedRange, GuessesPriorsAndMapsEntirelyBeyondItAreOneLineErrors) {
  const Pair p = make_pair(100, 56);
  const PreparedTarget t = prepared(p.target);
  AlignRequest req;
  Isometry3 guess = Isometry3::Identity();
  guess.translation() = Vec3(0, 1e308, 0);
  req.initial_guess = guess;
  EXPECT_NE(message_of([&] {
              run(p.source, t, "", req);
            }).find("initial guess: translation (0, 1e+308, 0) m is beyond the supported range"),
            std::string::npos);
  EXPECT_THROW(run(p.source, t, "base", req), InvalidArgument);  // every strategy
  req = AlignRequest{};
  for (const PriorSigma& bad :
       {PriorSigma{1.0, 1e308}, PriorSigma{1e300, 1.0}, PriorSigma{1.0, kInf}, PriorSigma{0.0, 1.0},
        PriorSigma{1e-300, 1.0}, PriorSigma{1.0, 1e-10}}) {
    req.prior = bad;
    EXPECT_NE(message_of([&] { run(p.source, t, "", req); }).find("prior sigma: prior"),
              std::string::npos);
  }
  SourceLandmarks all_far = p.source;
  for (Vec3& x : all_far.positions) x.x() += 1e300;
  EXPECT_NE(message_of([&] {
              run(all_far, t);
            }).find("every source landmark (100) is beyond the supported range"),
            std::string::npos);
  // A non-finite landmark is corrupt input, not a far one: refused, naming it.
  SourceLandmarks nan = p.source;
  nan.positions[3].z() = kNaN;
  EXPECT_EQ(message_of([&] { run(nan, t); }), "source landmark 3 is not finite");
  // The engines themselves refuse what align() leaves out (their precondition).
  SourceLandmarks s;
  s.positions = p.source.positions;
  s.positions[3].y() = -1e200;
  const Pipeline adaptive(find_preset("adaptive").spec);
  EXPECT_NE(message_of([&] {
              adaptive.run(s.view(), t);
            }).find("source landmark 3 is not finite or beyond 1e+15 m"),
            std::string::npos);
  s.positions = p.source.positions;
  PipelineRequest far;
  far.initial_guess = guess;
  EXPECT_THROW(adaptive.run(s.view(), t, far), InvalidArgument);
  EXPECT_THROW(Pipeline(find_preset("robust_obs").spec).run(s.view(), t, far), InvalidArgument);
}

TEST(SupportedRange, AtTheEdgeOfTheRangeTheDefaultGivesAResult) {
  // Guess and prior at the range's edge: no intermediate overflows (the gate's pose sigma, the
  // vote window). So wide a prior bounds nothing: the search is global and finds the truth.
  const Pair p = make_pair(200, 57);
  const PreparedTarget t = prepared(p.target);
  AlignRequest req;
  Isometry3 guess = Isometry3::Identity();
  guess.translation() = Vec3(kMaxCoordinateM, -kMaxCoordinateM, kMaxCoordinateM);
  req.initial_guess = guess;
  req.prior = PriorSigma{kMaxAngleDeg, kMaxCoordinateM};
  const Summary wide = run(p.source, t, "", req);
  EXPECT_LT(transform_error(wide.registration.T_target_source, p.T_true).rotation_deg, 0.5);
  EXPECT_TRUE(wide.verdict.trustworthy) << wide.verdict.reason;
  // The tightest prior about that far guess: a finite result, not trusted.
  req.prior = PriorSigma{kMinSigma, kMinSigma};
  const Summary tiny = run(p.source, t, "", req);
  EXPECT_TRUE(tiny.registration.T_target_source.matrix().allFinite());
  EXPECT_FALSE(std::isnan(tiny.registration.final_score_m2));
  EXPECT_FALSE(tiny.verdict.trustworthy);
  // Every other strategy starts there: a finite estimate.
  req.prior.reset();
  for (const char* s : {"base", "robust_obs", "mutual"}) {
    EXPECT_TRUE(run(p.source, t, s, req).registration.T_target_source.matrix().allFinite()) << s;
  }
}

TEST(SupportedRange, FarLandmarksWithinItDoNotDerailTheDefault) {
  // One landmark 1e9 m (and one 1e15 m) away in otherwise good maps, a source landmark among
  // the search's samples (index 0 always is): the search's centre and vote grid are not pulled
  // away by it (before, the search found no hypothesis and the pipeline read past an empty list).
  const Pair p = make_pair(600, 58);
  const PreparedTarget t = prepared(p.target);
  for (double far : {1e9, 1e12, kMaxCoordinateM}) {
    SourceLandmarks s = p.source;
    s.positions[0] = Vec3(far, 0, 0);
    const Summary o = run(s, t);
    const TransformError e = transform_error(o.registration.T_target_source, p.T_true);
    EXPECT_LT(e.rotation_deg, 0.5) << far;
    EXPECT_LT(e.translation_m, 0.02) << far;
    EXPECT_TRUE(o.verdict.trustworthy) << far << ": " << o.verdict.reason;
    EXPECT_EQ(o.source_left_out, 0u);
  }
  // The target too.
  Map far_target = p.target;
  far_target.landmarks[0].p_world = Vec3(0, 0, -1e11);
  const Summary o = run(p.source, prepared(far_target));
  EXPECT_LT(transform_error(o.registration.T_target_source, p.T_true).rotation_deg, 0.5);
  EXPECT_TRUE(o.verdict.trustworthy) << o.verdict.reason;
}

TEST(SupportedRange, MapsFarFromTheirOriginsAreSearchedRelativeToTheirCentres) {
  // Both maps 1e9 m from their origins (georeferenced coordinates): the votes are taken about
  // the maps' medians, so the search finds the yaw (before, every vote fell outside the grid).
  const Points3 room = test::room_points(600, 59);
  const Vec3 offset(1e9, -2e9, 0);
  Points3 target, source;
  const Isometry3 T_true = Eigen::Translation3d(offset) *
                           pose_from_xyz_rpy_deg(0.2, 0.1, 0, 0, 0, 40.0) *
                           Eigen::Translation3d(-offset);
  for (const Vec3& q : room) target.push_back(q + offset);
  source = transform_points(T_true.inverse(), target);
  const std::vector<YawHypothesis> h =
      yaw_vote_hypotheses(source, target, Vec3::UnitZ(), Vec3::UnitZ(), 0.05, YawVoteOptions{});
  ASSERT_FALSE(h.empty());
  const TransformError e = transform_error(h.front().T_target_source, T_true);
  EXPECT_LT(e.rotation_deg, 2.0);
  // At 1e9 m a rotation error moves the origin far; compare where the maps are.
  EXPECT_LT((h.front().T_target_source * source[0] - target[0]).norm(), 0.3);
}

TEST(FirstException, TheFirstExceptionOfAParallelLoopReachesTheCaller) {
  FirstException error;
  int completed = 0;
#pragma omp parallel for reduction(+ : completed)
  for (int i = 0; i < 64; ++i) {
    error.capture([&] {
      if (i % 3 == 0) throw InvalidArgument("iteration " + std::to_string(i));
      ++completed;
    });
  }
  EXPECT_EQ(completed, 64 - 22);  // the others ran to the end
  EXPECT_THROW(error.rethrow(), InvalidArgument);
  FirstException none;
  none.capture([] {});
  EXPECT_NO_THROW(none.rethrow());
}

}  // namespace
}  // namespace lmalign
