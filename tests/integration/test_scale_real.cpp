// Alignment with a free scale (Sim(3): registration/similarity.hpp, AlignRequest::scale) on real
// maps moved by a known similarity, checked against the truth.
// - The TUM desk pair (desk_gt_a onto desk_gt_b; their true transform is the identity,
//   method.md §6) with the source moved by a similarity of scale 0.37 or 3.0.
// - The desk map cut into two overlapping windows (split_map, re-triangulated from each window's
//   observations) with one window moved by a similarity of scale 0.37.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "lmalign/core/geometry.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/map/transform.hpp"
#include "lmalign/registration/presets.hpp"
#include "support/data_path.hpp"
#include "support/real_pair.hpp"
#include "support/windows.hpp"

namespace lmalign {
namespace {

Similarity3 similarity(double scale, double x, double y, double z, double roll_deg,
                       double pitch_deg, double yaw_deg) {
  return {scale, pose_from_xyz_rpy_deg(x, y, z, roll_deg, pitch_deg, yaw_deg)};
}

/// The map's landmarks moved by S (positions, covariances times s^2, its frames' up axis).
SourceLandmarks moved(const Map& map, const Similarity3& S) {
  return SourceLandmarks::from_map(transform_map(map, S));
}

/// The largest distance of the map's landmarks from their centroid, metres (its extent).
double extent_m(const Map& map) {
  Vec3 c = Vec3::Zero();
  for (const Landmark& l : map.landmarks) c += l.p_world;
  c /= static_cast<double>(map.landmarks.size());
  double r = 0.0;
  for (const Landmark& l : map.landmarks) r = std::max(r, (l.p_world - c).norm());
  return r;
}

Summary align_free(const std::string& preset, const SourceLandmarks& source,
                   const PreparedTarget& target) {
  AlignRequest request;
  request.scale = ScaleMode::kFree;
  return align(find_preset(preset), source.view(), target, request);
}

using ScaleDesk = test::RealPairTest;

TEST_F(ScaleDesk, DefaultRecoversScale037And3) {
  // The truth for the moved source is S^-1 (desk_gt_a onto desk_gt_b is the identity).
  // Measured (2026-11-23): scale error 0.84% for both (the same estimate, 0.9916 of the
  // truth's scale, is found for scale 1: the two RGB-D windows themselves differ by about that,
  // within what the pair's truth is known to, ~0.7 deg and ~1 cm over a 1 m map); rotation
  // 0.85 deg, translation 1.8 cm (rigid: 0.60 deg, 1.4 cm).
  for (const double scale : {0.37, 3.0}) {
    const Similarity3 S = similarity(scale, 0.3, -0.5, 0.2, 10, 0, 40);
    const Summary r = align_free("adaptive", moved(*source_, S), *target_);
    const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
    EXPECT_TRUE(r.scale.free);
    EXPECT_NEAR(r.scale.scale * scale, 1.0, 0.01) << "scale " << scale;
    EXPECT_LT(e.scale_error, 0.01) << "scale " << scale;
    EXPECT_LT(e.rotation_deg, 1.5) << "scale " << scale;
    EXPECT_LT(e.translation_m, 0.03) << "scale " << scale;
    EXPECT_TRUE(r.verdict.trustworthy) << "scale " << scale << ": " << r.verdict.reason;
    // The scale's standard deviation is determined and small against the scale.
    ASSERT_TRUE(r.scale.covariance_7x7.has_value());
    EXPECT_GT(r.scale.scale_sd, 0.0);
    EXPECT_LT(r.scale.scale_sd, 0.01 * r.scale.scale);
  }
}

// Refined from the truth (the truth as the initial guess, a prior of 1 deg / 0.3 m), on a pair
// whose true scale is 1 but whose source says its scale is arbitrary: the similarity scores at
// least as the rigid answer on the same pair (its objective is the gated score's), and its
// scale's standard deviation covers its error (within 2 sd). Issue 36: the 7-DoF refinement
// of main ed907dd ended 0.84% off on the desk pair with an sd of 0.036%, and below the rigid
// answer's score.
void expect_the_similarity_scores_at_least_the_rigid_answer(const Map& source_map,
                                                            const PreparedTarget& target,
                                                            const std::string& what) {
  const SourceLandmarks source = SourceLandmarks::from_map(source_map);
  AlignRequest request;
  request.initial_guess = Isometry3::Identity();
  request.prior = PriorSigma{1.0, 0.3};
  request.scale = ScaleMode::kFixed;
  const Summary rigid = align(recommended_preset(), source.view(), target, request);
  request.scale = ScaleMode::kFree;
  const Summary free = align(recommended_preset(), source.view(), target, request);
  ASSERT_TRUE(rigid.verdict.trustworthy) << what << ": " << rigid.verdict.reason;
  ASSERT_TRUE(free.verdict.trustworthy) << what << ": " << free.verdict.reason;
  EXPECT_GE(free.verdict.score, rigid.verdict.score) << what;
  ASSERT_TRUE(free.scale.covariance_7x7.has_value()) << what;
  EXPECT_LE(std::abs(free.scale.scale - 1.0), 2.0 * free.scale.scale_sd)
      << what << ": scale " << free.scale.scale << " +- " << free.scale.scale_sd;
}

TEST_F(ScaleDesk, FromTheTruthTheSimilarityScoresAtLeastTheRigidAnswer) {
  expect_the_similarity_scores_at_least_the_rigid_answer(*source_, *target_, "desk pair");
}

TEST(ScaleKitti, FromTheTruthTheSimilarityScoresAtLeastTheRigidAnswer) {
  const std::string a = test::data_file("kitti_stereo_vo/kitti_vo_a_ovl.txt");
  const std::string b = test::data_file("kitti_stereo_vo/kitti_vo_b_ovl.txt");
  LMALIGN_REQUIRE_FILE(a);
  LMALIGN_REQUIRE_FILE(b);
  expect_the_similarity_scores_at_least_the_rigid_answer(read_map(a), PreparedTarget(read_map(b)),
                                                         "kitti overlapping pair");
}

TEST_F(ScaleDesk, PaperStrategyWithUmeyamaScaleRecoversAScaledMap) {
  // The paper's covariance strategy starts at the identity: the source is the desk map scaled
  // by 0.37 about the origin, turned by 3 deg and shifted by 2 cm (the initial scale from the
  // spacings undoes most of the scale). Umeyama with scale refines it.
  // The pairs must be bounded (--max-distance): with the paper's unbounded nearest neighbours,
  // the landmarks outside the overlap pull the scale down round after round (measured: 1.88
  // for a truth of 2.70 after 20 rounds).
  const Similarity3 S = similarity(0.37, 0.02, 0.0, -0.01, 1, 0, 3);
  AlignRequest request;
  request.scale = ScaleMode::kFree;
  const SourceLandmarks src = moved(*source_, S);
  const Summary unbounded = align(find_preset("covariance"), src.view(), *target_, request);
  EXPECT_GT(similarity_error(unbounded.similarity() * S, Similarity3{}).scale_error, 0.1);
  request.max_distance_m = 0.05;
  const Summary r = align(find_preset("covariance"), src.view(), *target_, request);
  const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
  EXPECT_TRUE(r.scale.free);
  EXPECT_LT(e.scale_error, 0.01);
  EXPECT_LT(e.rotation_deg, 1.5);
  EXPECT_LT(e.translation_m, 0.05) << r.FullReport();
}

TEST_F(ScaleDesk, FixedScaleIsTheRigidAlignment) {
  // scale fixed (and auto on metric maps) runs the rigid pipeline: identical results.
  const Similarity3 S = similarity(1.0, 0.02, 0.0, -0.01, 1, 0, 3);
  const SourceLandmarks src = moved(*source_, S);
  AlignRequest fixed;
  fixed.scale = ScaleMode::kFixed;
  const Summary a = align(find_preset("covariance"), src.view(), *target_, fixed);
  const Summary b = align(find_preset("covariance"), src.view(), *target_, AlignRequest{});
  EXPECT_FALSE(a.scale.free);
  EXPECT_EQ(a.scale.scale, 1.0);
  EXPECT_TRUE(a.registration.T_target_source.matrix() == b.registration.T_target_source.matrix());
}

TEST(ScaleSplitDesk, OverlappingWindowsOneMovedBySimilarity037) {
  // map_fr1_desk.txt cut into frames 0-159 and 80-239, each window's landmarks re-triangulated
  // from its own observations (as `lmalign split --retriangulate`); window A moved by a
  // similarity of scale 0.37. The windows share the map's world frame: the truth is S^-1.
  // Measured (2026-11-23): scale error 0.07%, rotation 0.09 deg, translation 1.4 mm.
  const std::string path = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(path);
  MapReadOptions read;
  read.min_observations = 0;
  const Map map = read_map(path, read);
  const Map a = test::retriangulated_window(map, 0, 159);
  const Map b = test::retriangulated_window(map, 80, 239);
  ASSERT_GT(a.landmarks.size(), 1000u);
  ASSERT_GT(b.landmarks.size(), 1000u);
  const Similarity3 S = similarity(0.37, 0.4, 0.1, -0.3, 5, -10, 60);
  const PreparedTarget target(b);
  const Summary r = align_free("adaptive", moved(a, S), target);
  const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
  EXPECT_LT(e.scale_error, 0.01);
  EXPECT_LT(e.rotation_deg, 1.0);
  EXPECT_LT(e.translation_m, 0.01 * extent_m(b));
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
}

// The benchmark's desk_retri_120_sim3 (bench/accuracy.yaml): the ground-truth desk map cut into
// frames 0-119 and 100-239, each window re-triangulated (parallax >= 2 deg), window A moved by a
// similarity of scale 0.37.
// - By default the correspondences measure the scale before the search (docs/scale.md, step 5):
//   with the oriented descriptors within 0.1% of the truth (measured 2026-11-25; with the
//   yaw-invariant ones alone, 8.6% off), so one search and one attempt suffice.
// - Without that measurement (scale.measure_steps=0) the spacing ratio starts the scale 10% off,
//   more than the search absorbs: the first pass at the initial scale is not trusted, and the
//   first pass a rung away (1/1.12 of it, 1.3% off) is, without a complete search (2026-11-29;
//   before, the complete search's hypotheses were concluded at that rung).
//   Measured (2026-11-24): initial 2.988 for 2.703; scale error 0.54%, 0.07 deg, 1.0 cm; one
//   search and two rungs (the run before the rungs searched twice: 2.2x the rigid time, now
//   1.2-1.4x).
// - A measured scale's first pass takes the poses the measurement found at that scale instead
//   of searching again (2026-11-26: 1.77x the rigid time before, 1.05x after).
TEST(ScaleSplitDesk, TheCorrespondencesMeasureTheScaleElseAFirstPassARungAwayAnswers) {
  const std::string path = test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt");
  LMALIGN_REQUIRE_FILE(path);
  const Map map = read_map(path);
  const auto parallax = [](SplitOptions& o) { o.min_parallax_deg = 2.0; };
  const Map a = test::retriangulated_window(map, 0, 119, parallax);
  const Map b = test::retriangulated_window(map, 100, 239, parallax);
  const Similarity3 S = similarity(0.37, 0.3, -0.2, 0.1, 5, -10, 60);
  const PreparedTarget target(b);
  const SourceLandmarks source = moved(a, S);
  const double truth_scale = 1.0 / 0.37;
  AlignRequest request;
  request.scale = ScaleMode::kFree;
  for (const bool measured : {true, false}) {
    if (!measured) request.settings.emplace_back("scale.measure_steps", std::string("0"));
    const Summary r = align(find_preset("adaptive"), source.view(), target, request);
    const double initial_off = std::abs(r.scale.initial_scale / truth_scale - 1.0);
    const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
    EXPECT_LT(e.scale_error, 0.01) << "measured " << measured;
    EXPECT_LT(e.rotation_deg, 1.0) << "measured " << measured;
    EXPECT_LT(e.translation_m, 0.01 * extent_m(b)) << "measured " << measured;
    EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
    const auto note = [&](const std::string& name) {
      for (const auto& [key, value] : r.initialisation.notes) {
        if (key == name) return true;
      }
      return false;
    };
    EXPECT_EQ(note("first pass poses from the scale's measurement"), measured);
    if (measured) EXPECT_FALSE(note("first pass correspondence matches"));
    if (measured) {
      ASSERT_TRUE(std::isfinite(r.scale.measured_factor));
      EXPECT_LT(initial_off, 0.01);
      EXPECT_EQ(r.scale.attempts, 1);
      EXPECT_EQ(r.scale.searches, 1);
    } else {
      // The premise: the initial scale is off by more than the search absorbs (about 6%).
      EXPECT_TRUE(std::isnan(r.scale.measured_factor));
      EXPECT_GT(initial_off, 0.06);
      // No complete search: the first pass at the initial scale is not trusted, the first pass
      // of the search again a rung away is (Pipeline::run: the searches again's first passes
      // come before any complete search; until 2026-11-29 the complete search ran at the
      // initial scale and its hypotheses were concluded at that rung).
      EXPECT_EQ(r.scale.attempts, 2);
      EXPECT_EQ(r.scale.searches, 2);
      EXPECT_TRUE(note("first pass correspondence matches"));
      EXPECT_FALSE(note("deeper pass after an untrusted answer"));
    }
  }
}

// The benchmark's desk_retri_60 (bench/accuracy.yaml): the ground-truth desk map cut into frames
// 20-79 and 50-109, each window re-triangulated (parallax >= 2 deg); 788 and 578 landmarks.
// (The tests call LMALIGN_REQUIRE_FILE on the map first.)
struct DeskRetri60 {
  static Map window(Id first, Id last) {
    static const Map map =
        read_map(test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt"));
    return test::retriangulated_window(map, first, last,
                                       [](SplitOptions& o) { o.min_parallax_deg = 2.0; });
  }
  Map a = window(20, 79);
  Map b = window(50, 109);
  PreparedTarget target{b};
};

bool has_note(const Summary& r, const std::string& name) {
  for (const auto& [key, value] : r.initialisation.notes) {
    if (key == name) return true;
  }
  return false;
}

// The first pass (search.first_pass) must stand a scale a little off: a free scale's first pass
// runs at a scale up to half a rung (6%) from the truth. With the window scaled by 1.02 (a fixed
// scale) it finds the truth with search.first_pass_poses = 128 (the default since 2026-11-29)
// and misses it with 64, the complete search's number (measured 2026-11-29 in steps of 0.5%:
// with 64 the first pass missed at every scale error above +0.5%, with 128 at none within
// +-5%).
TEST(ScaleSplitDesk, TheFirstPassStandsASmallScaleError) {
  LMALIGN_REQUIRE_FILE(test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt"));
  const DeskRetri60 desk;
  const Similarity3 S = similarity(1.02, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  const SourceLandmarks source = moved(desk.a, S);
  for (const int poses : {128, 64}) {
    SCOPED_TRACE("first pass poses " + std::to_string(poses));
    AlignRequest request;
    request.settings.emplace_back("search.first_pass_poses", std::to_string(poses));
    request.settings.emplace_back("search.complete_search", std::string("check"));
    const Summary r = align(find_preset("adaptive"), source.view(), desk.target, request);
    const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
    const bool right = e.rotation_deg < 1.0 && e.translation_m < 0.1;  // the benchmark's basin
    EXPECT_EQ(right, poses == 128) << e.rotation_deg << " deg, " << e.translation_m << " m";
    EXPECT_EQ(r.verdict.trustworthy, poses == 128) << r.verdict.reason;
  }
}

// Moved by a similarity of 0.6 (the benchmark's desk_retri_60_sim3), the spacings put the
// initial scale 13% off, the measurement is not decisive, and the first pass there is not
// trusted. The first passes at the other scales come next (Pipeline::run), and the one a rung
// below answers, trusted, without any complete search (measured 2026-11-29: 1.8 s, 2.9 times
// the rigid alignment; 6.0 s and 10 times before, with a complete search at each of three
// scales).
TEST(ScaleSplitDesk, TheFirstPassesAtOtherScalesComeBeforeAnyCompleteSearch) {
  LMALIGN_REQUIRE_FILE(test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt"));
  const DeskRetri60 desk;
  const Similarity3 S = similarity(0.6, 0.1, 0.3, 0.0, 0.0, 0.0, 150.0);
  const Summary r = align_free("adaptive", moved(desk.a, S), desk.target);
  const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
  EXPECT_LT(e.scale_error, 0.01);
  EXPECT_LT(e.rotation_deg, 1.0);
  EXPECT_LT(e.translation_m, 0.01 * extent_m(desk.b));
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  // The premise: the initial scale is off by more than a first pass stands.
  EXPECT_GT(std::abs(r.scale.initial_scale * 0.6 - 1.0), 0.06);
  EXPECT_GE(r.scale.searches, 2);
  EXPECT_TRUE(has_note(r, "first pass correspondence matches"));
  EXPECT_FALSE(has_note(r, "deeper pass after an untrusted answer"));
  // A trusted answer there is checked as the first scale's would be: with every rival above 20%
  // calling for the check (trust.alias_ambiguity), the deeper pass runs at that answer's scale
  // with the answer among its hypotheses ("previous pass"), and keeps it, trusted.
  AlignRequest checked;
  checked.scale = ScaleMode::kFree;
  checked.settings.emplace_back("trust.alias_ambiguity", std::string("0.2"));
  const Summary c = align(find_preset("adaptive"), moved(desk.a, S).view(), desk.target, checked);
  EXPECT_TRUE(c.verdict.trustworthy) << c.verdict.reason;
  EXPECT_LT(similarity_error(c.similarity() * S, Similarity3{}).rotation_deg, 1.0);
  EXPECT_TRUE(has_note(c, "deeper pass to check a trusted answer"));
  EXPECT_FALSE(has_note(c, "deeper pass after an untrusted answer"));
  bool kept = false;
  for (const RefinedHypothesis& h : c.hypotheses) kept = kept || h.start.origin == "previous pass";
  EXPECT_TRUE(kept);
}

// A free scale whose truth lies midway between two rungs (scale.half_rung). Re-triangulated
// desk windows 0-59 and 170-229 (no shared frame; rigid, the default is right and trusted), the
// source moved by a similarity of 2.2. The scale's lead puts the initial scale 6% below the
// truth and the rung above it 5% above: both first passes miss the truth (a first pass stands
// about 5%), and so does the complete search after them, 5.7 deg off, lower. The first pass half
// a rung from the best, towards its better neighbour, finds it (measured 2026-11-29, a held-out
// pair: 148.6 -> 162.1). It stays refused there (a pose 11 deg away at 71%, its residuals above
// their covariances); what is asserted is the search: the answer the score prefers. Run in
// Release only (SANITIZE_EXCLUDE): about 10 s there.
TEST(ScaleSplitDesk, AFirstPassHalfARungAwayFindsATruthMidwayBetweenRungs) {
  LMALIGN_REQUIRE_FILE(test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt"));
  const Map a = DeskRetri60::window(0, 59);
  const PreparedTarget target(DeskRetri60::window(170, 229));
  const Similarity3 S = similarity(2.2, 0.3, -0.2, 0.1, 0.0, 0.0, -100.0);
  const Summary r = align_free("adaptive", moved(a, S), target);
  const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
  EXPECT_LT(e.rotation_deg, 3.0);
  EXPECT_LT(e.scale_error, 0.02);
  EXPECT_LT(e.translation_m, 0.05);
  AlignRequest off;
  off.scale = ScaleMode::kFree;
  off.settings.emplace_back("scale.half_rung", std::string("false"));
  const Summary o = align(find_preset("adaptive"), moved(a, S).view(), target, off);
  const SimilarityError eo = similarity_error(o.similarity() * S, Similarity3{});
  EXPECT_GT(eo.rotation_deg, 5.0);
  EXPECT_FALSE(o.verdict.trustworthy);
  EXPECT_GT(r.verdict.score, 1.05 * o.verdict.score);
  EXPECT_EQ(r.scale.attempts, o.scale.attempts + 1);
}

// Trust precision with a free scale. Re-triangulated KITTI windows 1-13 and 14-26
// (bench/accuracy.yaml's kitti_full_retri_disjoint, no shared frame; rigid, the default finds
// the truth by its complete search, trusted) with the source moved by a similarity. The
// spacings put the initial scale about 28% below the truth's, outside the searches' five
// scales, and poses at wrong scales score more than the truth's rigid answer does (94-106
// against 89): the score cannot place this pair, so its result must not be trusted. Measured
// 2026-11-29 over 40 similarities (scales 0.4-2.5, yaws 10-100 deg, roll 0 or 3 deg): until
// then 10 were trusted, each 29 deg / 16 m off at a scale 23% off (a first pass of 64 poses
// saw no rival, and the check by correspondences one at 54%); now none, every one ending at
// the same pose (the complete search at the best first pass's scale sees a rival at 85%).
// Run in Release only (SANITIZE_EXCLUDE): about 10 s there.
TEST(ScaleKittiWindows, ASimilarityTheScoreCannotPlaceIsNotTrusted) {
  const std::string file = test::data_file("kitti_stereo_vo/kitti_vo_full.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const auto window = [&](Id first, Id last) {
    return test::retriangulated_window(full, first, last, [](SplitOptions& o) {
      o.min_parallax_deg = 1.0;
      o.triangulation.intrinsics = {721.5377, 721.5377, 609.5593, 172.854};  // KITTI 00, left
    });
  };
  const PreparedTarget target(window(14, 26));
  const Similarity3 S = similarity(0.4, 0.5, 1.0, -0.3, 0.0, 0.0, 10.0);  // trusted until then
  const Summary r = align_free("adaptive", moved(window(1, 13), S), target);
  const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
  EXPECT_FALSE(r.verdict.trustworthy)
      << r.verdict.reason << ": " << e.rotation_deg << " deg, " << e.translation_m << " m off";
  // The second line of defence: with the first pass of 64 poses (which trusted this answer, saw
  // no rival), the check of a free scale's trusted answer is the complete search, which finds
  // the rival at 85% (a second correspondence search, search.check's default for rigid maps,
  // saw one at 54% and kept the answer trusted).
  AlignRequest narrow;
  narrow.scale = ScaleMode::kFree;
  narrow.settings.emplace_back("search.first_pass_poses", std::string("64"));
  const Summary n = align(find_preset("adaptive"), moved(window(1, 13), S).view(), target, narrow);
  EXPECT_FALSE(n.verdict.trustworthy) << n.verdict.reason;
  EXPECT_NE(n.verdict.reason.find("ambiguous"), std::string::npos) << n.verdict.reason;
}

// A Sim(3) pair cut from a real COLMAP model (real_formats/colmap_txt_kapture_maupertuis, written
// by COLMAP: 4 images of a chateau, 1,039 points, arbitrary scale): images 1-2 and images 3-4,
// each window's landmarks re-triangulated from its own two images (split --retriangulate),
// window A moved by a similarity. The windows share the model's frame: the truth is S^-1.
// Measured (2026-11-24, scale 0.37): 741 and 535 landmarks; scale error 0.011%, 0.03 deg,
// translation 0.06% of the extent, trusted, at the first initial scale.
TEST(ScaleColmapReal, ImagePairsOfTheMaupertuisModelOneMovedBySimilarity) {
  const std::string dir = test::data_file("real_formats/colmap_txt_kapture_maupertuis");
  LMALIGN_REQUIRE_FILE(dir);
  const Map model = read_any_map(dir);
  const Map a = test::retriangulated_window(model, 1, 2);
  const Map b = test::retriangulated_window(model, 3, 4);
  ASSERT_GT(a.landmarks.size(), 500u);
  ASSERT_GT(b.landmarks.size(), 500u);
  const PreparedTarget target(b);
  for (const Similarity3& S : {similarity(0.37, 0.3, -0.2, 0.1, 5, -10, 60),
                               similarity(2.7, -4.0, 1.0, 6.0, -20, 15, -130)}) {
    const Summary r = align_free("adaptive", moved(a, S), target);
    const SimilarityError e = similarity_error(r.similarity() * S, Similarity3{});
    EXPECT_LT(e.scale_error, 0.01) << "scale " << S.scale;
    EXPECT_LT(e.rotation_deg, 1.0) << "scale " << S.scale;
    EXPECT_LT(e.translation_m, 0.01 * extent_m(b)) << "scale " << S.scale;
    EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  }
}

// The three monocular stella_vslam maps of one video
// (real_formats/stella_openhps_aist_living_lab_1, equirectangular camera, each of its own arbitrary
// scale), aligned pairwise by the default with the scale mode the CLI uses, auto: their headers say
// "arbitrary", so the scale is free. Against the similarities that SOURCE.md estimated from
// matching keyframes (an estimate, not ground truth: its own composition closes to 0.1% in scale):
// within 1% in scale and 1 deg, and trusted. The correspondences measure each scale before the
// search (issue 39, item 4; measured 2026-11-25: the initial scale within 0.4% of SOURCE.md's,
// the largest clique 3.7-4.8 times the largest at another scale), so one search suffices.
TEST(ScaleStellaReal, ThreeMonocularMapsAlignPairwiseWithinOnePercentOfSourceMd) {
  const std::string dir = "real_formats/stella_openhps_aist_living_lab_1/";
  struct Pair {
    const char* a;
    const char* b;
    double scale;
    Mat3 R;
  };
  Mat3 R1, R2, R3;  // SOURCE.md's rotation matrices, row-major
  R1 << 0.999993, -0.003646, 0.001103, 0.003649, 0.99999, -0.002655, -0.001093, 0.002659, 0.999996;
  R2 << 0.999826, 0.01738, -0.006787, -0.017191, 0.999489, 0.026942, 0.007252, -0.026821, 0.999614;
  R3 << 0.999738, 0.021504, -0.007805, -0.021262, 0.999328, 0.029848, 0.008441, -0.029675, 0.999524;
  for (const Pair& p :
       {Pair{"356a5a6e", "94eb7149", 0.74196, R1}, Pair{"356a5a6e", "4683e8ac", 0.79165, R2},
        Pair{"94eb7149", "4683e8ac", 1.06574, R3}}) {
    SCOPED_TRACE(std::string(p.a) + " -> " + p.b);
    const std::string a = test::data_file(dir + p.a + "/map.msg");
    const std::string b = test::data_file(dir + p.b + "/map.msg");
    LMALIGN_REQUIRE_FILE(a);
    LMALIGN_REQUIRE_FILE(b);
    const Map source = read_any_map(a);
    const Map target = read_any_map(b);
    ASSERT_EQ(source.header.scale, MapScale::kArbitrary);
    AlignRequest request;  // scale auto
    request.describe_maps(source.header, target.header);
    const SourceLandmarks src = SourceLandmarks::from_map(source);
    const Summary r = align(recommended_preset(), src.view(), PreparedTarget(target, {}), request);
    EXPECT_TRUE(r.scale.free);
    EXPECT_TRUE(std::isfinite(r.scale.measured_factor));
    EXPECT_NEAR(r.scale.initial_scale / p.scale, 1.0, 0.01);
    EXPECT_EQ(r.scale.searches, 1);
    EXPECT_NEAR(r.scale.scale / p.scale, 1.0, 0.01);
    const Mat3 dR = r.registration.T_target_source.linear() * p.R.transpose();
    EXPECT_LT(rotation_angle_deg(dR), 1.0);
    EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  }
}

}  // namespace
}  // namespace lmalign
