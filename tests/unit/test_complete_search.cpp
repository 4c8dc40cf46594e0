// The complete search (registration/stages/complete_search.hpp), its finer vote
// (yaw_vote_search.hpp: local_vote, the 3-D multi-peak vote) and the dominant-plane up axis
// (data_scales.hpp), on seeded synthetic scenes.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/stages/complete_search.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"
#include "lmalign/sim/road_sim.hpp"
#include "lmalign/sim/street_sim.hpp"
#include "support/align_preset.hpp"

namespace lmalign {
namespace {

struct ThreadCount {
  int saved = omp_get_max_threads();
  ~ThreadCount() { omp_set_num_threads(saved); }
};

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / kPi;
}

// An aperiodic street (street_sim.hpp), windows of 30 keyframes sharing half of them: the source
// moved by a pose far from the identity.
sim::SlamMapPair street(std::uint64_t seed) {
  sim::StreetSimOptions o;
  o.seed = seed;
  o.overlap = 0.5;
  o.num_landmarks = 3000;
  o.T_target_source = pose_from_xyz_rpy_deg(12.0, 0.5, -20.0, 0.0, 0.0, 140.0);
  return sim::simulate_street_pair(o);
}

// Issue 39's street pairs (`lmalign simulate --scene street --overlap 0.25 --frames 30
// --landmarks 3000 --seed SEED --transform ...`): windows sharing a quarter of their keyframes.
sim::SlamMapPair quarter_street(std::uint64_t seed, const Isometry3& T_target_source) {
  sim::StreetSimOptions o;
  o.seed = seed;
  o.overlap = 0.25;
  o.window_frames = 30;
  o.num_landmarks = 3000;
  o.T_target_source = T_target_source;
  return sim::simulate_street_pair(o);
}

// A held-out street seed (`lmalign simulate --scene street --overlap 0.25 --frames 30
// --landmarks 3000 --transform=-35,12,0,0,0,-75 --seed SEED`), ready to align.
struct HeldOutStreet {
  explicit HeldOutStreet(std::uint64_t seed)
      : pair(quarter_street(seed, pose_from_xyz_rpy_deg(-35, 12, 0, 0, 0, -75))),
        target(pair.target),
        source(SourceLandmarks::from_map(pair.source)) {}
  Summary align(const std::vector<std::string>& settings = {}) const {
    return test::align_with("adaptive", source, target, {settings});
  }
  // Right within 0.2 deg / 0.1 m, and trusted.
  void expect_right_and_trusted(const Summary& r) const {
    const TransformError e = transform_error(r.registration.T_target_source, pair.T_target_source);
    EXPECT_LT(e.rotation_deg, 0.2) << r.verdict.reason;
    EXPECT_LT(e.translation_m, 0.1) << r.verdict.reason;
    EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  }
  sim::SlamMapPair pair;
  PreparedTarget target;
  SourceLandmarks source;
};

TEST(CompleteSearch, FindsTheStreetPoseAndIsIndependentOfTheThreadCount) {
  // Measured: the complete search ends within 0.05 deg and 2 cm of the truth; the earlier
  // default (the vote's best yaw peaks, refined from the search's coarse resolution) ends tens
  // of metres along the street on this scene.
  const sim::SlamMapPair pair = street(33);
  const SourceLandmarks source = SourceLandmarks::from_map(pair.source);
  const PreparedTarget target(pair.target);
  const test::Ask o{{"estimate.half_sample_planes=0"}};
  ThreadCount restore;
  omp_set_num_threads(2);
  const Summary two = test::align_with("adaptive", source, target, o);
  const TransformError e = transform_error(two.registration.T_target_source, pair.T_target_source);
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.2);
  EXPECT_EQ(two.initialisation.initialisation, "global");
  omp_set_num_threads(1);
  const Summary one = test::align_with("adaptive", source, target, o);
  EXPECT_TRUE(one.registration.T_target_source.matrix() ==
              two.registration.T_target_source.matrix());
  EXPECT_EQ(one.verdict.score, two.verdict.score);
  ASSERT_EQ(one.hypotheses.size(), two.hypotheses.size());
  for (std::size_t i = 0; i < one.hypotheses.size(); ++i) {
    EXPECT_TRUE(one.hypotheses[i].T_refined.matrix() == two.hypotheses[i].T_refined.matrix());
  }
}

// Neighbouring windows of one street drive that share 3 of their 20 keyframes (15%): every pair
// of landmarks votes, so the coarse vote's counts are highest along the road where the windows'
// extents overlap most, and the truth sits on that ridge's flank. Ranked by their 3x3x3 votes,
// the peaks near the true yaw lay 5-13 m along the road and the search ended 20 deg and 171 deg
// off on these two alignments (refused); ranked by prominence above the background, it finds
// both (measured 2026-11-23: 0.01 deg / 1 cm, trusted).
TEST(CompleteSearch, FindsAShortStreetOverlapOnTheFlankOfTheVotesRidge) {
  sim::StreetSimOptions o;
  o.seed = 5;
  o.window_frames = 20;
  o.overlap = 0.15;
  o.num_landmarks = 3000;
  const sim::StreetWindows w = sim::simulate_street_windows(o, 3);
  for (std::size_t k = 0; k + 1 < w.maps.size(); ++k) {
    SCOPED_TRACE("window " + std::to_string(k) + " onto " + std::to_string(k + 1));
    const PreparedTarget target(w.maps[k + 1]);
    const Summary r = test::align_with("adaptive", SourceLandmarks::from_map(w.maps[k]), target,
                                       {{"estimate.half_sample_planes=0"}});
    const Isometry3 truth = w.T_world_map[k + 1].inverse() * w.T_world_map[k];
    const TransformError e = transform_error(r.registration.T_target_source, truth);
    EXPECT_LT(e.rotation_deg, 0.5);
    EXPECT_LT(e.translation_m, 0.1);
    EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  }
}

// Two windows of the simulated road with no overlap (its facades' window grid, lane dashes and
// ground texture repeat every 1.5-12 m): every pose is wrong, and sliding the source tens of
// metres along the road gates hundreds of landmarks. The first pass (the correspondence poses)
// finds such a slide with no rival among its poses and trusts it. Its residuals exceed their
// covariances, so the alias test needs every rival (Verdict::rivals_needed): the complete search
// runs as a deeper pass, finds the other slides, and the answer is refused. (Seed 8 until
// 2026-11-27: 61 m off, mean NIS 1.36 times its expectation, a rival at 72-83%. The refitted
// clique poses changed which slides the first pass proposes: of 16 roads (seeds 1-16, this
// transform) seeds 8, 11 and 14 were checked this way before, seed 11 now; every answer of the
// 16 is refused either way.) Since 2026-11-28 the first pass restarts its slides that lose to
// their starts (score.sharp_restart_share), and on seeds 1-16 it then finds seed 11's rival
// itself: refused without the check. The check is tested here with that restart off, as the net
// for an alias whose rivals the first pass misses. Since 2026-11-28 the check is a second
// correspondence search without the vote (search.check = correspondences): it refuses the slide
// as the complete search does (search.check = complete, also asserted). Measured 2026-11-29 (docs/
// accuracy.md, "Cheaper refinements: measured, not kept"): both checks refuse it by its inlier
// ratio (0.196 against 0.2), after the check refined the first pass's answer again and lowered
// its score (377 -> 355); kept at 377, the slide passed every test (inlier ratio 0.207, best
// rival 0.6955 against the alias margin 0.7). This net holds by a small margin.
TEST(CompleteSearch, AnAliasTheFirstPassTrustsIsCheckedByTheCompleteSearch) {
  sim::RoadSimOptions o;
  o.seed = 11;
  o.overlap = 0.0;
  o.num_landmarks = 3000;
  o.T_target_source = pose_from_xyz_rpy_deg(20, 5, 0, 0, 0, 120);
  const sim::SlamMapPair pair = sim::simulate_road_pair(o);
  const PreparedTarget target(pair.target);
  const SourceLandmarks source = SourceLandmarks::from_map(pair.source);
  for (const std::string check : {"correspondences", "complete"}) {
    SCOPED_TRACE(check);
    const Summary r = test::align_with("adaptive", source, target,
                                       {{"score.sharp_restart_share=0", "search.check=" + check}});
    EXPECT_FALSE(r.verdict.trustworthy) << r.verdict.reason;
    EXPECT_TRUE(r.verdict.rivals_needed);
    bool checked = false, by_correspondences = false;
    for (const auto& [name, value] : r.initialisation.notes) {
      checked = checked || name.rfind("deeper pass to check", 0) == 0;
      by_correspondences = by_correspondences || name == "check by correspondences";
    }
    EXPECT_TRUE(checked);
    EXPECT_EQ(by_correspondences, check == "correspondences");
    EXPECT_GT(transform_error(r.registration.T_target_source, pair.T_target_source).translation_m,
              10.0);
  }
  const Summary d = test::align_with("adaptive", source, target);  // the default: refused too
  EXPECT_FALSE(d.verdict.trustworthy) << d.verdict.reason;
}

// A road without overlap whose own score prefers a wrong slide: the accuracy benchmark's
// road_ovl0 (road scene, seed 11, no shared frame). Measured 2026-11-27: no search proposes a
// pose within 35 m of the truth; the answer, 91 m along the road, has a gated score of 330
// against the truth's 318 refined from the truth, its residuals 1.35 times their covariances, a
// rival slide at 72% of it on the scorer's samples (66% when refined and scored on every
// landmark) and an inlier ratio of 0.21 (the truth's 0.35); a slide 61 m off scores 391. Only the
// verdict protects it (the truth as a rival would refuse any slide), and two changes that
// measured better elsewhere trusted a wrong slide here (docs/accuracy.md, "The precise sub-map
// and rivals on every landmark: measured, not kept"): a trusted answer must be the truth.
TEST(CompleteSearch, ARoadWhoseScorePrefersAWrongSlideIsNeverTrustedWrong) {
  sim::RoadSimOptions o;
  o.seed = 11;
  o.overlap = 0.0;
  o.num_landmarks = 3000;
  const sim::SlamMapPair pair = sim::simulate_road_pair(o);
  const PreparedTarget target(pair.target);
  const Summary r = test::align_with("adaptive", SourceLandmarks::from_map(pair.source), target);
  const TransformError e = transform_error(r.registration.T_target_source, pair.T_target_source);
  if (r.verdict.trustworthy) {
    EXPECT_LT(e.rotation_deg, 2.0) << r.verdict.reason;
    EXPECT_LT(e.translation_m, 1.0) << r.verdict.reason;
  }
}

// The accuracy benchmark's road_ovl25 (road scene, seed 12, a quarter of the keyframes shared):
// the answer is the truth (0.02 deg / 2 cm), its residuals within their covariances, and a
// slide 46.8 m along the road is its best distinct rival. Until 2026-11-28 the hypotheses were
// scored on the 1,024 landmarks they were refined on, where that slide scored 87% of the answer
// and the answer was refused; on every landmark, against the answer itself, it scores 81%, under
// trust.max_ambiguity (docs/accuracy.md, "Refined on samples, scored on every landmark").
TEST(CompleteSearch, ARoadAnswerIsTrustedWhenItsRivalsAreScoredOnEveryLandmark) {
  sim::RoadSimOptions o;
  o.seed = 12;
  o.overlap = 0.25;
  o.num_landmarks = 3000;
  const sim::SlamMapPair pair = sim::simulate_road_pair(o);
  const PreparedTarget target(pair.target);
  const Summary r = test::align_with("adaptive", SourceLandmarks::from_map(pair.source), target);
  const TransformError e = transform_error(r.registration.T_target_source, pair.T_target_source);
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.2);
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  EXPECT_LT(r.verdict.ambiguity, 0.85);
  EXPECT_GT(r.verdict.ambiguity, 0.7);  // a real rival: the slide, measured against the answer
}

// A held-out street seed (`lmalign simulate --scene street --overlap 0.25 --frames 30
// --landmarks 3000 --transform=-35,12,0,0,0,-75 --seed 84`): a search's hypothesis starts 0.1
// deg / 0.1 m from the truth, and its refinement, whose gate starts a third of the search's
// resolution wide (1 m), carries it 1.1 m up the facades, scoring below its own start. Refined
// again from its start with a sharp gate (score.sharp_restart_share: its start scores more than
// 70% of the best refined hypothesis), it ends at the truth and is the answer, trusted. Without
// the restart the answer is that drifted pose, about 1 m off (docs/accuracy.md, "A hypothesis
// that loses to its start").
TEST(CompleteSearch, AHypothesisThatLosesToItsStartIsRefinedAgainWithASharpGate) {
  const HeldOutStreet street(84);
  const Summary r = street.align();
  street.expect_right_and_trusted(r);
  bool restarted = false;
  for (const RefinedHypothesis& h : r.hypotheses) restarted = restarted || h.sharp_restart;
  EXPECT_TRUE(restarted);
  const Summary off = street.align({"score.sharp_restart_share=0"});
  const TransformError e_off =
      transform_error(off.registration.T_target_source, street.pair.T_target_source);
  EXPECT_GT(e_off.translation_m, 0.5);
  EXPECT_LT(off.verdict.score, r.verdict.score);
  for (const RefinedHypothesis& h : off.hypotheses) EXPECT_FALSE(h.sharp_restart);
}

// A held-out street seed (`lmalign simulate --scene street --overlap 0.25 --frames 30
// --landmarks 3000 --transform=-35,12,0,0,0,-75 --seed 79`): the first pass is not trusted, and
// in the deeper pass a hypothesis refined on the scorer's 1,024 samples stops 0.27 deg / 0.87 m
// from the truth (gated score 186), below a slide 40 m along the street (187). As one of the
// deeper pass's contenders (score.contenders) it is refined again on every landmark, reaches the
// truth (341) and is the answer, trusted. Without the contenders the answer was the slide
// (docs/accuracy.md, "Contenders refined again"); since the first pass grows 128 poses
// (search.first_pass_poses, 2026-11-29) it is a pose that stopped 1.1 m short (190), refused.
TEST(CompleteSearch, TheDeeperPassRefinesItsContendersAgainOnMoreLandmarks) {
  const HeldOutStreet street(79);
  const Summary r = street.align();
  street.expect_right_and_trusted(r);
  bool again = false;
  for (const RefinedHypothesis& h : r.hypotheses) again = again || h.refined_again;
  EXPECT_TRUE(again);
  const Summary off = street.align({"score.contenders=0"});
  const TransformError e_off =
      transform_error(off.registration.T_target_source, street.pair.T_target_source);
  EXPECT_GT(e_off.translation_m, 0.5);
  EXPECT_FALSE(off.verdict.trustworthy);
  EXPECT_LT(off.verdict.score, 0.7 * r.verdict.score);
  for (const RefinedHypothesis& h : off.hypotheses) EXPECT_FALSE(h.refined_again);
}

// A held-out street seed (`lmalign simulate --scene street --overlap 0.25 --frames 30
// --landmarks 3000 --transform=-35,12,0,0,0,-75 --seed 64`): the first pass trusts the truth, but
// its residuals exceed their covariances as an alias's would (Verdict::rivals_needed), so a
// deeper pass checks it. The default's check is a second correspondence search without the vote
// (search.check = correspondences, docs/accuracy.md "The check by correspondences"): it keeps the
// same answer, trusted, that the complete search as the check (search.check = complete) keeps,
// at about half the time (measured 2026-11-28: 0.9 s against 1.9 s in Release).
TEST(CompleteSearch, ACheckByCorrespondencesKeepsTheAnswerTheCompleteSearchKeeps) {
  const HeldOutStreet street(64);
  // A note of the initialiser's report: its value, or -1 when it has none.
  auto note = [](const Summary& r, const std::string& key) {
    for (const auto& [name, value] : r.initialisation.notes) {
      if (name == key) return value;
    }
    return -1.0;
  };
  const Summary r = street.align();
  street.expect_right_and_trusted(r);
  EXPECT_EQ(note(r, "deeper pass to check an answer trusted without half samples"), 1.0);
  EXPECT_EQ(note(r, "check by correspondences"), 1.0);
  EXPECT_EQ(note(r, "search candidates"), 0.0);  // no vote

  const Summary full = street.align({"search.check=complete"});
  EXPECT_TRUE(full.verdict.trustworthy) << full.verdict.reason;
  EXPECT_EQ(note(full, "check by correspondences"), -1.0);
  EXPECT_GT(note(full, "search candidates"), 0.0);  // the vote's
  const TransformError d =
      transform_error(r.registration.T_target_source, full.registration.T_target_source);
  EXPECT_LT(d.rotation_deg, 1e-6);
  EXPECT_LT(d.translation_m, 1e-6);
}

// Issue 39's street seed 1 (`lmalign simulate --scene street --overlap 0.25 --frames 30
// --landmarks 3000 --transform 20,5,0,0,0,120 --seed 1`): the first pass's correspondence poses
// all lie 13-36 m along the street, so the complete search decides. Its pool holds a snapped
// candidate 0.6 deg / 0.3 m from the truth, but the fine score (unrefined, its gate widened by a
// third of two cells) ranks it 74th, and until 2026-11-27 the first round refined the 48
// best: the answer was a slide 32.6 m along the street, refused, whose gated score (119) is
// under half the truth's (258). With search.rank_keep 96 it is refined, and the answer is the
// truth (measured: 0.04 deg / 3 cm, trusted).
TEST(CompleteSearch, RefinesATruthCandidateTheFineScoreRanksBelowTheFirstFortyEight) {
  const sim::SlamMapPair pair = quarter_street(1, pose_from_xyz_rpy_deg(20, 5, 0, 0, 0, 120));
  const PreparedTarget target(pair.target);
  const Summary r = test::align_with("adaptive", SourceLandmarks::from_map(pair.source), target,
                                     {{"estimate.half_sample_planes=0"}});
  const TransformError e = transform_error(r.registration.T_target_source, pair.T_target_source);
  EXPECT_LT(e.rotation_deg, 0.5) << r.verdict.reason;
  EXPECT_LT(e.translation_m, 0.2) << r.verdict.reason;
  bool complete = false;
  for (const auto& [name, value] : r.initialisation.notes) {
    complete = complete || name == "search pool";
  }
  EXPECT_TRUE(complete);
}

// The complete search's input for a pair's maps, as the default sets it (a 3 deg yaw step).
struct StreetSearch {
  SourceLandmarks source;
  PreparedTarget target;
  CompleteSearchInput in;
  StreetSearch(const StreetSearch&) = delete;  // `in` points into the maps above
  StreetSearch& operator=(const StreetSearch&) = delete;
  explicit StreetSearch(const sim::SlamMapPair& pair)
      : source(SourceLandmarks::from_map(pair.source)), target(pair.target) {
    const DataScales ss = estimate_data_scales(source.positions, &source.covariances_m2);
    const DataScales ts = estimate_data_scales(target.points(), &target.covariances_m2());
    in.source = GateSide{&source.positions, &source.covariances_m2};
    in.target = &target;
    in.ups_source = {*source.up};
    in.ups_target = {*target.up_axis()};
    in.source_centre_m = ss.centre_m;
    in.source_radius_m = ss.radius_m;
    in.cell_m = 1.5 * std::max(ts.spacing_m, 2.0 * std::sin(1.5 * kPi / 180.0) * ss.radius_m);
    in.floor_m = std::max(ss.floor_m, ts.floor_m);
    in.coarse_sigma.translation_m = 0.6 * in.cell_m;
    in.coarse_sigma.rotation_rad = 0.9 * kPi / 180.0;
  }
};

TEST(CompleteSearch, ModesAreDistinctAndBestFirst) {
  const sim::SlamMapPair pair = street(33);
  StreetSearch search(pair);
  CompleteSearchInput& in = search.in;
  CompleteSearchOptions o;
  o.pool = 64;
  int refinements = 0;
  const SearchRefineFn no_refinement = [&](const Isometry3& start, const PoseSigma& sigma,
                                           const std::vector<std::uint32_t>& subset,
                                           int max_iterations) {
    EXPECT_GT(sigma.translation_m, 0.0);
    EXPECT_LT(sigma.translation_m, in.coarse_sigma.translation_m);
    EXPECT_FALSE(subset.empty());
    EXPECT_GE(max_iterations, 1);
#pragma omp atomic
    ++refinements;
    return start;
  };
  const CompleteSearchResult r = complete_search(in, o, no_refinement);
  EXPECT_GT(r.candidates, r.pooled);
  EXPECT_EQ(r.pooled, 64u);
  // Two rounds: at most rank_keep candidates, then at most round1_keep of them.
  EXPECT_LE(refinements, static_cast<int>(o.rank_keep + o.round1_keep));
  EXPECT_GE(refinements, static_cast<int>(2 * o.modes));
  ASSERT_EQ(r.modes.size(), o.modes);
  for (std::size_t i = 1; i < r.modes.size(); ++i) {
    EXPECT_GE(r.modes[i - 1].score, r.modes[i].score);
    for (std::size_t k = 0; k < i; ++k) {
      const Isometry3& a = r.modes[i].T_target_source;
      const Isometry3& b = r.modes[k].T_target_source;
      const double angle = Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
      EXPECT_GT(
          (a * in.source_centre_m - b * in.source_centre_m).norm() + angle * in.source_radius_m,
          o.distinct_cells * in.cell_m);
    }
  }
  CompleteSearchOptions bad = o;
  bad.peaks_per_yaw = 0;
  EXPECT_THROW(complete_search(in, bad, no_refinement), InvalidArgument);
  CompleteSearchInput no_ups = in;
  no_ups.ups_target.clear();
  EXPECT_THROW(complete_search(no_ups, o, no_refinement), InvalidArgument);
}

// More extra candidates (the correspondence poses, by clique size) than extra_keep: the pool
// takes extra_keep of them, from their own order and by the sharp score, in turn. On a street's
// repeated facades the largest cliques are often wrong, and a pose near the truth ranks low by
// size (28th-40th on issue 39's street seeds 27, 30 and 33).
TEST(CompleteSearch, ExtraCandidatesBeyondTheKeepAreChosenByTheSharpScoreToo) {
  const sim::SlamMapPair pair = street(33);
  StreetSearch search(pair);
  CompleteSearchInput& in = search.in;
  // 30 wrong poses (slides of 6-180 m and turns of 7-210 deg), then the truth: 31st.
  for (int i = 1; i <= 30; ++i) {
    in.extra_candidates.push_back(pose_from_xyz_rpy_deg(6.0 * i, 0.0, 0.0, 0.0, 0.0, 7.0 * i) *
                                  pair.T_target_source);
  }
  in.extra_candidates.push_back(pair.T_target_source);
  CompleteSearchOptions o;
  o.vote = false;
  const SearchRefineFn no_refinement = [](const Isometry3& start, const PoseSigma&,
                                          const std::vector<std::uint32_t>&, int) { return start; };
  const CompleteSearchResult r = complete_search(in, o, no_refinement);
  EXPECT_EQ(r.candidates, 0u);
  EXPECT_EQ(r.pooled, o.extra_keep);
  ASSERT_FALSE(r.modes.empty());
  // The best mode is the truth, snapped (measured 1.5 deg / 1.5 m off; unrefined here); every
  // wrong candidate is at least 6 m and 7 deg away.
  const TransformError e = transform_error(r.modes[0].T_target_source, pair.T_target_source);
  EXPECT_LT(e.rotation_deg, 3.0);
  EXPECT_LT(e.translation_m, 3.0);
  // At most extra_keep: all of them, in their own order, and the truth is not among them.
  o.extra_keep = 40;
  in.extra_candidates.pop_back();
  EXPECT_EQ(complete_search(in, o, no_refinement).pooled, 30u);
  CompleteSearchOptions bad = o;
  bad.extra_keep = 0;
  EXPECT_THROW(complete_search(in, bad, no_refinement), InvalidArgument);
}

TEST(LocalVote, SnapsAnOffCandidateToTheTrueTranslationAndYaw) {
  // A cloud of distinct landmarks; the candidate misses the truth by 1.5 cells and 2 deg: the
  // finer vote lands within a fine cell and a yaw step.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  Points3 target;
  for (int i = 0; i < 800; ++i) target.push_back(Vec3(u(rng), u(rng), 0.2 * u(rng)));
  const Isometry3 T_true = pose_from_xyz_rpy_deg(3.0, -2.0, 0.5, 0.0, 0.0, 35.0);
  Points3 source = transform_points(T_true.inverse(), target);
  const KdTree tree(target);
  const Vec3 centre = Vec3::Zero();
  const double cell = 1.0;
  const Isometry3 off =
      Isometry3(Eigen::Translation3d(1.5, 0.0, 0.0)) *
      Isometry3(Eigen::AngleAxisd(2.0 * kPi / 180.0, Vec3::UnitZ()).toRotationMatrix()) * T_true;
  LocalVoteOptions o;
  o.yaw_half_width_rad = 3.0 * kPi / 180.0;
  o.yaw_step_rad = 0.75 * kPi / 180.0;
  o.half_width_m = 2.0 * cell;
  o.cell_m = cell / 3.0;
  o.neighbours = 16;
  const YawHypothesis h = local_vote(source, tree, Vec3::UnitZ(), centre, off, o);
  ASSERT_GT(h.votes, 0u);
  const TransformError e = transform_error(h.T_target_source, T_true);
  EXPECT_LT(e.rotation_deg, 0.75);
  EXPECT_LT(e.translation_m, cell / 3.0);
  const TransformError before = transform_error(off, T_true);
  EXPECT_GT(before.translation_m, 1.0);
}

TEST(LocalVote, LandmarksOutsideTheTargetsBoxVoteAsInsideIt) {
  // Moved by the candidate, the source reaches 0.5 m past the target's box and 100 of its
  // landmarks lie 27-47 m from it: a moved landmark near the box still votes, one far from it has
  // no neighbour in the grid. The same vote with four far target landmarks that widen the box
  // around everything (never among anyone's 16 nearest: 800 landmarks are closer) must agree.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  Points3 target;
  for (int i = 0; i < 800; ++i) target.push_back(Vec3(u(rng), u(rng), 0.2 * u(rng)));
  Points3 source = target;
  for (Vec3& p : source) p.x() += 3.0;
  for (int i = 0; i < 100; ++i) source.push_back(Vec3(50.0 + u(rng), u(rng), u(rng)));
  Points3 wide = target;
  for (double s : {-1.0, 1.0}) {
    wide.push_back(Vec3(1000.0 * s, 1000.0 * s, 1000.0 * s));
    wide.push_back(Vec3(1000.0 * s, -1000.0 * s, 1000.0 * s));
  }
  const KdTree tree(target), wide_tree(wide);
  LocalVoteOptions o;
  o.yaw_half_width_rad = 3.0 * kPi / 180.0;
  o.yaw_step_rad = 0.75 * kPi / 180.0;
  o.half_width_m = 2.0;
  o.cell_m = 1.0 / 3.0;
  o.neighbours = 16;
  const Isometry3 T0 = pose_from_xyz_rpy_deg(-2.5, 0.3, 0.0, 0.0, 0.0, 1.0);
  const YawHypothesis a = local_vote(source, tree, Vec3::UnitZ(), Vec3::Zero(), T0, o);
  const YawHypothesis b = local_vote(source, wide_tree, Vec3::UnitZ(), Vec3::Zero(), T0, o);
  ASSERT_GT(a.votes, 0u);
  EXPECT_EQ(a.votes, b.votes);
  EXPECT_EQ(a.yaw_rad, b.yaw_rad);
  EXPECT_TRUE(a.T_target_source.matrix() == b.T_target_source.matrix());
  // The true translation is 3 m back along x: the snap finds it.
  EXPECT_NEAR((a.T_target_source * Vec3::Zero() - Vec3(-3.0, 0.0, 0.0)).norm(), 0.0, 1.0 / 3.0);
}

TEST(DominantPlane, FindsTheFloorUnderClutterAndAWall) {
  // A floor tilted 7 deg, clutter above it and a wall: the dominant plane within 60 deg of the
  // hint is the floor; the best-fitting plane of everything leans with the clutter.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Vec3 up = Eigen::AngleAxisd(7.0 * kPi / 180.0, Vec3::UnitX()) * Vec3::UnitZ();
  const Mat3 R = rotation_between(Vec3::UnitZ(), up);
  Points3 p;
  for (int i = 0; i < 600; ++i) p.push_back(R * Vec3(u(rng), u(rng), 0.002 * u(rng)));
  for (int i = 0; i < 250; ++i)
    p.push_back(R * Vec3(0.5 + 0.3 * u(rng), 0.3 * u(rng), 0.3 + 0.3 * u(rng)));
  for (int i = 0; i < 300; ++i)
    p.push_back(R * Vec3(1.0 + 0.002 * u(rng), u(rng), 0.5 + 0.5 * u(rng)));
  const std::optional<Vec3> n = dominant_plane_normal(p, Vec3::UnitZ(), 0.01);
  ASSERT_TRUE(n.has_value());
  EXPECT_LT(angle_deg(*n, up), 0.5);
  // Deterministic, and oriented like the hint.
  EXPECT_TRUE(*n == *dominant_plane_normal(p, Vec3::UnitZ(), 0.01));
  EXPECT_GT(angle_deg(*dominant_plane_normal(p, -Vec3::UnitZ(), 0.01), up), 179.0);
  // No plane: points in a ball.
  Points3 ball;
  for (int i = 0; i < 500; ++i) ball.push_back(Vec3(u(rng), u(rng), u(rng)));
  EXPECT_FALSE(dominant_plane_normal(ball, Vec3::UnitZ(), 0.01).has_value());
  EXPECT_FALSE(dominant_plane_normal(p, Vec3::UnitZ(), 0.0).has_value());
}

}  // namespace
}  // namespace lmalign
