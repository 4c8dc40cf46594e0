// The adaptive pipeline (issue 18; registration/adaptive.hpp) on the real pairs whose true
// transform is the identity: the TUM desk pair (desk_gt_a onto desk_gt_b; method.md §6) and the
// KITTI stereo-VO pairs (kitti_vo_a onto kitti_vo_b, disjoint; kitti_vo_a_ovl onto
// kitti_vo_b_ovl, overlapping; /work/shared/data/kitti_stereo_vo/SOURCE.md). The source is
// displaced by D (positions, covariances and its up axis), so the estimate should be D^-1.
// Bounds are the errors measured here (noted at each test) with margin; the desk truth itself
// is only known to ~0.7 deg and ~1 cm, the KITTI one to the VO's accuracy (~0.05 deg, 2-5 cm).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "support/align_preset.hpp"
#include "support/data_path.hpp"
#include "support/real_pair.hpp"
#include "support/windows.hpp"

namespace lmalign {
namespace {

/// The source `s` moved by D: p -> D p, C -> R C R^T, up -> R up (R = D's rotation).
SourceLandmarks displaced(const SourceLandmarks& s, const Isometry3& D) { return s.moved(D); }

/// The error of an estimate for the source displaced by D against the truth D^-1 (the maps'
/// true transform is the identity).
TransformError error_of(const Summary& r, const Isometry3& D) {
  return transform_error(r.registration.T_target_source * D, Isometry3::Identity());
}

/// The answer for a source displaced by D is within `rotation_deg` / `translation_m` of the
/// truth (the identity) and trusted.
void expect_right_and_trusted(const Summary& r, const Isometry3& D, double rotation_deg,
                              double translation_m) {
  const TransformError e = error_of(r, D);
  EXPECT_LT(e.rotation_deg, rotation_deg);
  EXPECT_LT(e.translation_m, translation_m);
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
}

/// A pair of maps loaded once per suite: source_ (as SourceLandmarks::from_map) and target_.
template <typename Files>
class PairTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!std::filesystem::exists(Files::source()) || !std::filesystem::exists(Files::target())) {
      return;
    }
    source_ =
        std::make_unique<SourceLandmarks>(SourceLandmarks::from_map(read_map(Files::source())));
    target_ = std::make_unique<PreparedTarget>(read_map(Files::target()));
  }
  static void TearDownTestSuite() {
    source_.reset();
    target_.reset();
  }
  void SetUp() override {
    LMALIGN_REQUIRE_FILE(Files::source());
    LMALIGN_REQUIRE_FILE(Files::target());
  }
  static inline std::unique_ptr<SourceLandmarks> source_;
  static inline std::unique_ptr<PreparedTarget> target_;
};

struct DeskFiles {
  static std::string source() { return test::real_pair_source_file(); }
  static std::string target() { return test::real_pair_target_file(); }
};
struct KittiFiles {
  static std::string source() { return test::data_file("kitti_stereo_vo/kitti_vo_a.txt"); }
  static std::string target() { return test::data_file("kitti_stereo_vo/kitti_vo_b.txt"); }
};
struct KittiOverlapFiles {
  static std::string source() { return test::data_file("kitti_stereo_vo/kitti_vo_a_ovl.txt"); }
  static std::string target() { return test::data_file("kitti_stereo_vo/kitti_vo_b_ovl.txt"); }
};

using AdaptiveDesk = PairTest<DeskFiles>;
using AdaptiveKitti = PairTest<KittiFiles>;
using AdaptiveKittiOverlap = PairTest<KittiOverlapFiles>;

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

TEST_F(AdaptiveDesk, UpAxesOfBothMapsAreNearTheMotionCaptureZ) {
  // estimate_up_axis from the frames of a hand-held camera pitched down ~30 deg. Measured:
  // 4.2 deg (desk_gt_a) and 4.4 deg (desk_gt_b) from the maps' z (the motion-capture up).
  ASSERT_TRUE(source_->up.has_value());
  ASSERT_TRUE(target_->up_axis().has_value());
  EXPECT_LT(angle_deg(*source_->up, Vec3::UnitZ()), 7.0);
  EXPECT_LT(angle_deg(*target_->up_axis(), Vec3::UnitZ()), 7.0);
}

TEST_F(AdaptiveKitti, UpAxesOfBothMapsAreNearMinusY) {
  // A car's camera: y down. Measured: 0.65 deg (kitti_vo_a) and 0.90 deg (kitti_vo_b) from -y.
  ASSERT_TRUE(source_->up.has_value());
  ASSERT_TRUE(target_->up_axis().has_value());
  EXPECT_LT(angle_deg(*source_->up, -Vec3::UnitY()), 2.0);
  EXPECT_LT(angle_deg(*target_->up_axis(), -Vec3::UnitY()), 2.0);
}

TEST_F(AdaptiveDesk, ReachesTheTruthFromTable1sDisplacement) {
  // Measured: 0.59 deg, 1.4 cm; inlier ratio 0.86, ambiguity 0.77; ~1.2 s.
  const Isometry3 D = pose_from_xyz_rpy_deg(0, 1, 0.4, 10, 0, 22.5);
  const Summary r = test::align_with("adaptive", displaced(*source_, D), *target_);
  expect_right_and_trusted(r, D, 1.5, 0.03);
}

TEST_F(AdaptiveDesk, ReachesTheTruthFromAFarStart) {
  // Yaw 150 deg about z and 2 m in x-y (test_global_real_pair.cpp's far start).
  // Measured: 0.60 deg, 1.4 cm; inlier ratio 0.86, ambiguity 0.76; ~1.3 s.
  const Isometry3 D = pose_from_xyz_rpy_deg(1.5, -1.3, 0, 0, 0, 150);
  const Summary r = test::align_with("adaptive", displaced(*source_, D), *target_);
  expect_right_and_trusted(r, D, 1.5, 0.03);
}

TEST_F(AdaptiveKitti, DisjointPairStaysAtTheTruthUnderATightPrior) {
  // The prior is tighter than the search's resolution (half a yaw step, one vote cell): the
  // guess alone is refined (the prior's own search, init.prior_check=off). Measured: 0.079 deg,
  // 4.0 cm; inlier ratio 0.33 (trust needs 0.2); 0.1 s.
  const Isometry3 guess = Isometry3::Identity();
  PriorSigma prior;
  prior.rotation_deg = 1.0;
  prior.translation_m = 0.2;
  const Summary r =
      test::align_with("adaptive", *source_, *target_, {{"init.prior_check=off"}, guess, prior});
  const TransformError e = error_of(r, Isometry3::Identity());
  EXPECT_EQ(r.initialisation.initialisation, "given");
  EXPECT_LT(e.rotation_deg, 0.2);
  EXPECT_LT(e.translation_m, 0.1);
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
}

/// A far start on KITTI: yaw 100 deg about the maps' up axis (-y, camera y down) and 8 m in the
/// horizontal x-z plane.
Isometry3 kitti_far_start() {
  Isometry3 D = Isometry3::Identity();
  D.linear() = Eigen::AngleAxisd(100.0 * M_PI / 180.0, -Vec3::UnitY()).toRotationMatrix();
  D.translation() = Vec3(8.0 * std::cos(0.6), 0.0, 8.0 * std::sin(0.6));
  return D;
}

TEST_F(AdaptiveKitti, DisjointPairFromAFarStartWithoutAGuess) {
  // Measured: 0.079 deg, 4.0 cm (the same estimate as from the truth); inlier ratio 0.33,
  // ambiguity 0.48; ~1.1 s.
  const Isometry3 D = kitti_far_start();
  const Summary r = test::align_with("adaptive", displaced(*source_, D), *target_);
  expect_right_and_trusted(r, D, 1.0, 0.3);
}

TEST_F(AdaptiveKittiOverlap, OverlappingPairFromAFarStart) {
  // The same far start as the disjoint pair's. Measured: 0.010 deg, 3 mm; inlier ratio 0.63,
  // ambiguity 0.19; ~1.1 s.
  const Isometry3 D = kitti_far_start();
  const Summary r = test::align_with("adaptive", displaced(*source_, D), *target_);
  expect_right_and_trusted(r, D, 0.2, 0.05);
}

// ----------------------------------------------------------------------------- priors
// Issue 41: a prior is a hint, checked against the maps (init.prior_check = rivals, the
// default). The
// guesses of the issue, wrong by more than their sigma, never give a trusted wrong answer; a
// right guess (inside one sigma) is trusted and right. The maps' true transform is the identity.

/// A guess off the truth by `yaw_deg` about `up` and by `offset_m` (target frame).
Isometry3 off_guess(const Vec3& up, double yaw_deg, const Vec3& offset_m) {
  Isometry3 G = Isometry3::Identity();
  G.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, up.normalized()).toRotationMatrix();
  G.translation() = offset_m;
  return G;
}

/// The answer for `guess` under `prior`, checked by the global search (`check` empty: the
/// default, "rivals"; "off": the prior's search alone, its answer checked against its window):
/// never trusted when wrong (rotation_ok_deg, translation_ok_m).
Summary checked_against_prior(const SourceLandmarks& source, const PreparedTarget& target,
                              const Isometry3& guess, PriorSigma prior, double rotation_ok_deg,
                              double translation_ok_m, const std::string& check = "") {
  std::vector<std::string> settings;
  if (!check.empty()) settings.push_back("init.prior_check=" + check);
  const Summary r = test::align_with("adaptive", source.view(), target, {settings, guess, prior});
  const TransformError e = transform_error(r.registration.T_target_source, Isometry3::Identity());
  const bool right = e.rotation_deg < rotation_ok_deg && e.translation_m < translation_ok_m;
  EXPECT_TRUE(right || !r.verdict.trustworthy)
      << "trusted and wrong: " << e.rotation_deg << " deg, " << e.translation_m
      << " m; reason: " << r.verdict.reason;
  EXPECT_EQ(r.initialisation.prior_checked, check != "off");
  return r;
}

TEST_F(AdaptiveDesk, AWrongPriorIsCheckedAndARightOneTrusted) {
  // Sigma 2 deg, 5 cm. The issue's guess 1.0 m / 130 deg off gave an answer 131.7 deg / 0.93 m
  // off, trusted: the maps prefer the truth, outside the window; not trusted, and the verdict
  // names where the maps put it. A guess inside one sigma is trusted.
  PriorSigma prior;
  prior.rotation_deg = 2.0;
  prior.translation_m = 0.05;
  const Summary wrong = checked_against_prior(
      *source_, *target_, off_guess(Vec3::UnitZ(), 130.0, Vec3(0.7, 0.7, 0.0)), prior, 5.0, 0.1);
  EXPECT_FALSE(wrong.verdict.trustworthy);
  EXPECT_NE(wrong.verdict.reason.find("the maps prefer a pose outside the prior's window"),
            std::string::npos)
      << wrong.verdict.reason;
  // The maps put it at the truth, which every other test trusts; the first pass found it, and
  // the complete search, which cannot make that result trusted, did not run.
  EXPECT_TRUE(wrong.verdict.outside_prior_window);
  EXPECT_TRUE(wrong.verdict.trusted_but_for_prior_window);
  const TransformError wrong_e =
      transform_error(wrong.registration.T_target_source, Isometry3::Identity());
  EXPECT_LT(wrong_e.rotation_deg, 5.0);
  EXPECT_LT(wrong_e.translation_m, 0.1);
  for (const auto& [name, value] : wrong.initialisation.notes) {
    EXPECT_NE(name, "deeper pass after an untrusted answer");
  }
  const Summary right = checked_against_prior(
      *source_, *target_, off_guess(Vec3::UnitZ(), 1.0, Vec3(0.02, -0.03, 0.0)), prior, 5.0, 0.1);
  EXPECT_TRUE(right.verdict.trustworthy) << right.verdict.reason;
  // A right prior costs no search of its own: a global mode lies inside its window.
  bool inside = false;
  for (const auto& [name, value] : right.initialisation.notes) {
    inside = inside || (name == "global modes inside the prior's window" && value >= 1.0);
  }
  EXPECT_TRUE(inside);
  EXPECT_EQ(right.initialisation.initialisation, "prior");
}

/// Each guess, wrong by more than its prior, by the prior's search alone (init.prior_check=off,
/// the default before issue 41): refused, by the window check and the verdict's questions.
void expect_refused_by_the_priors_search_alone(const SourceLandmarks& source,
                                               const PreparedTarget& target,
                                               const std::vector<Isometry3>& guesses,
                                               double sigma_deg, double sigma_m,
                                               double rotation_ok_deg, double translation_ok_m) {
  PriorSigma prior;
  prior.rotation_deg = sigma_deg;
  prior.translation_m = sigma_m;
  for (const Isometry3& guess : guesses) {
    const Summary r = checked_against_prior(source, target, guess, prior, rotation_ok_deg,
                                            translation_ok_m, "off");
    EXPECT_FALSE(r.verdict.trustworthy) << r.verdict.reason;
  }
}

TEST_F(AdaptiveDesk, TheIssuesWrongPriorsAreNotTrustedByThePriorsSearchAlone) {
  // Sigma 2 deg, 5 cm: the issue's guesses 1.0 m / 130 deg off (an answer 131.7 deg off,
  // trusted) and 90 deg off (97.7 deg off, not converged, trusted) end untrusted.
  expect_refused_by_the_priors_search_alone(*source_, *target_,
                                            {off_guess(Vec3::UnitZ(), 130.0, Vec3(0.7, 0.7, 0.0)),
                                             off_guess(Vec3::UnitZ(), 90.0, Vec3::Zero())},
                                            2.0, 0.05, 5.0, 0.1);
}

TEST_F(AdaptiveKittiOverlap, TheIssuesWrongDriftPriorsAreNotTrustedByThePriorsSearchAlone) {
  // Sigma 1 deg, 0.3 m: the issue's guesses 39.5 m / -9 deg off (41.8 m off, trusted) and
  // (3, 0, -38) m without rotation (38.6 m off, not converged, trusted on 21 gated inliers) end
  // untrusted.
  expect_refused_by_the_priors_search_alone(*source_, *target_,
                                            {off_guess(-Vec3::UnitY(), -9.0, Vec3(0.0, 0.0, 39.5)),
                                             off_guess(-Vec3::UnitY(), 0.0, Vec3(3.0, 0.0, -38.0))},
                                            1.0, 0.3, 5.0, 1.0);
}

TEST_F(AdaptiveKittiOverlap, AWrongDriftPriorIsCheckedAndARightOneTrusted) {
  // Sigma 1 deg, 0.3 m. The issue's guess 39.5 m / -9 deg off gave an answer 41.8 m off,
  // trusted. A guess inside one sigma is trusted.
  PriorSigma prior;
  prior.rotation_deg = 1.0;
  prior.translation_m = 0.3;
  const Summary wrong = checked_against_prior(
      *source_, *target_, off_guess(-Vec3::UnitY(), -9.0, Vec3(0.0, 0.0, 39.5)), prior, 5.0, 1.0);
  EXPECT_FALSE(wrong.verdict.trustworthy) << wrong.verdict.reason;
  const Summary right = checked_against_prior(
      *source_, *target_, off_guess(-Vec3::UnitY(), 0.5, Vec3(0.2, 0.0, -0.1)), prior, 5.0, 1.0);
  EXPECT_TRUE(right.verdict.trustworthy) << right.verdict.reason;
}

/// The re-triangulated window [first, last] of the motion-capture-anchored desk map (as
/// `lmalign split --retriangulate`), in that map's frame: two windows share their true frame.
Map desk_window(const Map& full, Id first, Id last) {
  return test::retriangulated_window(full, first, last);
}

/// The window [first, last] of the whole KITTI drive, each landmark re-estimated from the
/// window's own left-image pixels (as bench/accuracy.yaml's kitti_full_retri_*: 1 deg minimum
/// parallax), in the drive's frame: the truth between two windows is the identity.
Map kitti_window(const Map& full, Id first, Id last) {
  return test::retriangulated_window(full, first, last, [](SplitOptions& o) {
    o.min_parallax_deg = 1.0;
    o.triangulation.intrinsics = {721.5377, 721.5377, 609.5593, 172.854};  // KITTI 00, left
  });
}

TEST(AdaptiveDeskWindows, AShortHandHeldWindowsUpAxisIsRescuedByItsLandmarkPlane) {
  // Two 30-frame windows, 10 frames shared (75-104 and 95-124). The hand-held camera rolls, so
  // the frames put the target's up axis 46 deg from the vertical (estimate_up_axis); its
  // landmarks' plane (the desk) puts it within 9 deg. Measured: with the frames' axes alone
  // (second_up_min_angle_deg = 180) the search ends 12.9 deg and 23 cm off; with the plane's
  // as a second candidate, 0.12 deg and 2 mm, trusted (mean NIS 1.70 of 2.89).
  const std::string file = test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const Map a = desk_window(full, 75, 104);
  const Map b = desk_window(full, 95, 124);
  const PreparedTarget target(b);
  ASSERT_TRUE(target.up_axis().has_value());
  const Vec3 z = Vec3::UnitZ();
  EXPECT_GT(angle_deg(*target.up_axis(), z), 30.0);
  const std::optional<Vec3> plane = landmark_plane_normal(target.points(), *target.up_axis());
  ASSERT_TRUE(plane.has_value());
  EXPECT_LT(angle_deg(*plane, z), 12.0);

  const Isometry3 D = pose_from_xyz_rpy_deg(0.8, -0.5, 0.1, 0.0, 0.0, 100.0);
  const Summary r =
      test::align_with("adaptive", displaced(SourceLandmarks::from_map(a), D), target);
  EXPECT_GE(r.initialisation.ups_target.size(), 2u);
  expect_right_and_trusted(r, D, 0.5, 0.01);
}

// Issue 41: a right prior on an alias. Re-triangulated desk windows with no shared frame (0-119
// onto 120-239, bench/accuracy.yaml's desk_retri_120_ovl0), a right prior (1 deg and 2 cm off,
// sigma 2 deg / 5 cm): the answer is right and trusted, although a pose 11 deg away, outside the
// prior's window, scores more than trust.alias_ambiguity of it while the residuals exceed their
// covariances. Until 2026-11-27 the prior told that alias apart (prior_tells_apart,
// trust_gated.cpp). Since the viewing-direction rival test, that turned rival is measured on the
// pairs seen from compatible directions. Since 2026-11-28 the rivals are scored on every landmark
// against the answer itself, and the best distinct rival inside the window scores 69%. A rival
// within trust.max_ambiguity would still refuse it. Measured 2026-11-28: the prior sweep's 10 right
// priors trusted, 0 of 20 wrong ones. The first pass's answer needs every rival, and the maps'
// own poses confirm the prior, so the check is the correspondence search without the vote
// (search.check; since 2026-11-28: 1.4 s, against 3.1 s for the complete search, which finds the
// alias; both are run here).
TEST(AdaptiveDeskWindows, ARightPriorOnAnAliasGivesATrustedRightAnswer) {
  const std::string file = test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const Map a = desk_window(full, 0, 119);
  const Map b = desk_window(full, 120, 239);
  const PreparedTarget target(b);
  const SourceLandmarks source = SourceLandmarks::from_map(a);
  PriorSigma prior;
  prior.rotation_deg = 2.0;
  prior.translation_m = 0.05;
  const Isometry3 guess = pose_from_xyz_rpy_deg(0.02, 0.0, 0.0, 0.0, 0.0, 1.0);
  // The default, and the complete search as the check (search.check=complete), which finds the
  // alias.
  for (const std::string check : {"correspondences", "complete"}) {
    SCOPED_TRACE(check);
    const Summary r =
        test::align_with("adaptive", source, target, {{"search.check=" + check}, guess, prior});
    EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
    const TransformError e = transform_error(r.registration.T_target_source, Isometry3::Identity());
    EXPECT_LT(e.rotation_deg, 3.0);
    EXPECT_LT(e.translation_m, 0.06);
    EXPECT_LT(r.verdict.ambiguity, test::preset_setting("adaptive", "trust.max_ambiguity"));
    EXPECT_GT(r.verdict.mean_nis,
              test::preset_setting("adaptive", "trust.alias_nis_ratio") * r.verdict.expected_nis);
    EXPECT_FALSE(r.verdict.alias_waived_by_prior);
    bool by_correspondences = false;
    for (const auto& [name, value] : r.initialisation.notes) {
      by_correspondences = by_correspondences || name == "check by correspondences";
    }
    EXPECT_EQ(by_correspondences, check == "correspondences");
    if (check == "correspondences") continue;
    // The alias the complete search finds: a refined hypothesis outside the window (turned from
    // the guess by more than 3 sigma) scoring at least trust.alias_ambiguity of the answer, with
    // the residuals above their covariances.
    const double alias = test::preset_setting("adaptive", "trust.alias_ambiguity");
    bool outside_alias = false;
    for (const RefinedHypothesis& h : r.hypotheses) {
      outside_alias = outside_alias || (transform_error(h.T_refined, guess).rotation_deg >
                                            3.0 * prior.rotation_deg &&
                                        h.score >= alias * r.verdict.score);
    }
    EXPECT_TRUE(outside_alias);
  }
}

// Issue 41: a right prior tells an alias outside its window apart (prior_tells_apart,
// trust_gated.cpp). Re-triangulated desk windows of 30 frames with no shared frame (100-129
// onto 130-159, bench/accuracy.yaml's desk_retri_30_ovl0), a right prior (1 deg and 2 cm off,
// sigma 2 deg / 5 cm). A pose turned 124 deg from the answer scores 72% of it while the
// residuals are 1.5 times their covariances: the alias test alone refuses that (without a prior
// the answer is refused so). The rival lies outside the prior's window and the answer inside
// it, so the prior tells them apart: trusted. Measured 2026-11-28: 3.6 deg / 5.7 cm off; the
// prior sweep's 10 right priors trusted, 0 of 20 wrong ones. An answer trusted on the prior's
// word (Verdict::alias_waived_by_prior) is checked by the complete search, whatever search.check
// says: the first pass's answer here is 6.8 deg / 15 cm off, and only the complete search's vote
// finds the 3.6-degree pose (a check by correspondences kept the 6.8-degree one, trusted:
// docs/accuracy.md, "The check by correspondences").
TEST(AdaptiveDeskWindows, ARightPriorTellsAnAliasOutsideItsWindowApart) {
  const std::string file = test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const Map a = desk_window(full, 100, 129);
  const Map b = desk_window(full, 130, 159);
  const PreparedTarget target(b);
  PriorSigma prior;
  prior.rotation_deg = 2.0;
  prior.translation_m = 0.05;
  const Isometry3 guess = pose_from_xyz_rpy_deg(0.02, 0.0, 0.0, 0.0, 0.0, 1.0);
  const Summary r =
      test::align_with("adaptive", SourceLandmarks::from_map(a), target, {{}, guess, prior});
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  const TransformError e = transform_error(r.registration.T_target_source, Isometry3::Identity());
  EXPECT_LT(e.rotation_deg, 5.0);
  EXPECT_LT(e.translation_m, 0.1);
  // What the alias test alone would refuse: a distinct pose at least trust.alias_ambiguity of
  // the answer while the residuals exceed their covariances; that pose outside the window.
  EXPECT_GE(r.verdict.ambiguity, test::preset_setting("adaptive", "trust.alias_ambiguity"));
  EXPECT_LT(r.verdict.ambiguity, test::preset_setting("adaptive", "trust.max_ambiguity"));
  EXPECT_GT(r.verdict.mean_nis,
            test::preset_setting("adaptive", "trust.alias_nis_ratio") * r.verdict.expected_nis);
  ASSERT_TRUE(r.verdict.rival_T_target_source.has_value());
  EXPECT_GT(transform_error(*r.verdict.rival_T_target_source, guess).rotation_deg,
            3.0 * prior.rotation_deg);
  EXPECT_TRUE(r.verdict.alias_waived_by_prior);
  double vote_candidates = -1.0;
  bool checked = false;
  for (const auto& [name, value] : r.initialisation.notes) {
    if (name == "search candidates") vote_candidates = value;
    checked = checked || name.rfind("deeper pass to check", 0) == 0;
    EXPECT_NE(name, "check by correspondences");
  }
  EXPECT_TRUE(checked);
  EXPECT_GT(vote_candidates, 0.0);  // the complete search's vote ran
}

// Re-triangulated windows of the desk map whose votes never proposed the truth (the search kept
// the best-voted yaw peaks): the complete search finds the pose its score prefers. Measured on a
// 2-core AMD EPYC guest, 2026-11-23: 0.06 deg / 2 mm (60 frames) and 0.04 deg / 1 mm (30 frames),
// both trusted; the earlier default ended 145 deg and 19 deg off.
TEST(AdaptiveDeskWindows, TheCompleteSearchFindsShortWindowsTheVotesMissed) {
  const std::string file = test::data_file("tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  struct Case {
    Id a0, a1, b0, b1;
  };
  for (const Case& k : {Case{20, 79, 50, 109}, Case{100, 129, 115, 144}}) {
    SCOPED_TRACE(std::to_string(k.a0) + "-" + std::to_string(k.a1) + " onto " +
                 std::to_string(k.b0) + "-" + std::to_string(k.b1));
    const Map a = desk_window(full, k.a0, k.a1);
    const Map b = desk_window(full, k.b0, k.b1);
    const PreparedTarget target(b);
    const Isometry3 D = pose_from_xyz_rpy_deg(0.4, -0.3, 0.05, 0.0, 0.0, -120.0);
    const Summary r =
        test::align_with("adaptive", displaced(SourceLandmarks::from_map(a), D), target);
    expect_right_and_trusted(r, D, 1.0, 0.02);
  }
}

// Issue 39, item 3: the verdict asks the observations. Re-triangulated KITTI windows 1-13 and
// 14-26 (bench/accuracy.yaml's kitti_full_retri_disjoint: no shared frame). The answer is the
// truth; a pose 18.7 m / 46 deg away scores 90% of it by the gated score, which alone refuses the
// answer as ambiguous (trust.view_rival_margin_deg=180 turns the viewing test off). At the answer
// the two maps saw their shared landmarks from directions within a few degrees; the rivals are
// turned by more than they spread, and counting only the pairs seen from directions within the
// answer's limit the strongest (18.5 m / 28 deg) scores 71%: trusted. Measured on the 2-core AMD
// EPYC guest, 2026-11-27, with every gated pair counting alike (scales.evidence_spacings=0). The
// gated score that weighs each pair by what it can tell (the default from 2026-11-27) lowers the
// rivals' share (the last check), but not below the margin: since the complete search's first
// round refines 96 candidates (search.rank_keep), it finds one 18.4 m / 48 deg away at 86% of
// it (83% before). The viewing directions are what separate it.
TEST(AdaptiveKittiWindows, ViewingDirectionsSeparateARivalTheGeometryCannot) {
  const std::string file = test::data_file("kitti_stereo_vo/kitti_vo_full.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const PreparedTarget target(kitti_window(full, 14, 26));
  const SourceLandmarks source = SourceLandmarks::from_map(kitti_window(full, 1, 13));
  const Summary with = test::align_with("adaptive", source, target, {});
  EXPECT_TRUE(with.verdict.trustworthy) << with.verdict.reason;
  const TransformError e = error_of(with, Isometry3::Identity());
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.2);
  ASSERT_TRUE(with.verdict.rival_T_target_source.has_value());
  EXPECT_GT(with.verdict.rival_angle_deg, 10.0);  // a turned rival, not a slide
  EXPECT_LT(with.verdict.ambiguity, test::preset_setting("adaptive", "trust.max_ambiguity"));
  const Summary without =
      test::align_with("adaptive", source, target,
                       {{"trust.view_rival_margin_deg=180", "scales.evidence_spacings=0"}});
  EXPECT_FALSE(without.verdict.trustworthy);
  EXPECT_NE(without.verdict.reason.find("ambiguous"), std::string::npos) << without.verdict.reason;
  EXPECT_LT(error_of(without, Isometry3::Identity()).translation_m, 0.2);  // the same answer
  // The viewing test off, the evidence weight on: the rival's share is lower than the plain
  // score's (measured 86% against 90%: refused, within the margin).
  const Summary weighed =
      test::align_with("adaptive", source, target, {{"trust.view_rival_margin_deg=180"}});
  EXPECT_LT(weighed.verdict.ambiguity, without.verdict.ambiguity);
  EXPECT_LT(error_of(weighed, Isometry3::Identity()).translation_m, 0.2);
}

// Re-triangulated KITTI windows 1-13 and 14-26 (bench/accuracy.yaml's kitti_full_retri_disjoint:
// no shared frame). The answer is the truth, trusted (the test above says why). Until 2026-11-26
// the search depended on how the source's frame was turned about its up axis (its centre was a
// coordinate-wise median, its grid of yaws had a fixed phase): turned by 15 angles 30 deg
// apart, it ended 44-49 deg off at 4 of them, and turned by -30 deg it trusted a pose 122 deg
// off (its best rival at 77%: the first pass alone let it through). Now every turn gives the same
// hypotheses, answer and verdict (docs/accuracy.md, "The search turns with the maps").
TEST(AdaptiveKittiWindows, TheAnswerAndItsVerdictTurnWithTheSource) {
  const std::string file = test::data_file("kitti_stereo_vo/kitti_vo_full.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const Map a = kitti_window(full, 1, 13);
  const PreparedTarget target(kitti_window(full, 14, 26));
  const SourceLandmarks source = SourceLandmarks::from_map(a);
  ASSERT_EQ(source.view_directions.size(), source.positions.size());
  std::size_t known = 0;
  for (const Vec3& v : source.view_directions) known += v.isZero() ? 0 : 1;
  EXPECT_GT(known, source.positions.size() / 2);
  const Summary r = test::align_with("adaptive", source, target, {});
  const TransformError e = error_of(r, Isometry3::Identity());
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.2);
  EXPECT_TRUE(r.verdict.trustworthy) << r.verdict.reason;
  // Turned by 75 deg about the camera's y axis (near the drive's up; the up axis is estimated
  // again) and moved: one of the turns that ended 44-49 deg off.
  const Isometry3 B = pose_from_xyz_rpy_deg(4.0, 0.0, -9.0, 0.0, 75.0, 0.0);
  const Summary t =
      test::align_with("adaptive", SourceLandmarks::from_map(transform_map(a, B)), target, {});
  const Isometry3 back = t.registration.T_target_source * B;
  EXPECT_LT((back.linear() - r.registration.T_target_source.linear()).norm(), 1e-6);
  EXPECT_LT((back.translation() - r.registration.T_target_source.translation()).norm(), 1e-5);
  EXPECT_NEAR(t.verdict.score, r.verdict.score, 1e-6 * r.verdict.score);
  EXPECT_EQ(t.verdict.reason, r.verdict.reason);
}

// Issue 37, item 4 (priors are hints, never walls): a merge's prior edge (init.
// prior_complete_search = "check") whose prior's own search misses the truth inside its window
// gets the maps' first pass, which finds it. Re-triangulated KITTI windows 1-6 onto 6-11 (one
// shared frame, as bench/merge_real.py's kitti_retri w5_f6), a guess 1.9 deg / 0.67 m off,
// inside its sigmas: the prior's search alone ends 1.3 deg / 1.9 m off (it leaves the truth even
// from the truth itself), refused; the check ends 0.04 deg / 1 cm off, trusted. Measured on the
// 2-core AMD EPYC guest, 2026-11-26. Since 2026-11-28 the prior's own search restarts a
// hypothesis that loses to its start with a sharp gate (score.sharp_restart_share) and finds the
// truth itself (1 cm, trusted); the rescue is tested with that restart off.
TEST(AdaptiveKittiWindows, APriorEdgesCheckRescuesWhatThePriorsOwnSearchMissed) {
  const std::string file = test::data_file("kitti_stereo_vo/kitti_vo_full.txt");
  LMALIGN_REQUIRE_FILE(file);
  const Map full = read_map(file);
  const PreparedTarget target(kitti_window(full, 6, 11));
  const SourceLandmarks source = SourceLandmarks::from_map(kitti_window(full, 1, 6));
  PriorSigma prior;
  prior.rotation_deg = 4.2;
  prior.translation_m = 1.5;
  const Isometry3 guess = pose_from_xyz_rpy_deg(0.0, -0.5, -0.45, -1.8, 0.0, -0.8);
  const Summary restarted =
      test::align_with("adaptive", source, target, {{"init.prior_check=off"}, guess, prior});
  EXPECT_TRUE(restarted.verdict.trustworthy) << restarted.verdict.reason;
  EXPECT_LT(error_of(restarted, Isometry3::Identity()).translation_m, 0.1);
  const Summary alone =
      test::align_with("adaptive", source, target,
                       {{"init.prior_check=off", "score.sharp_restart_share=0"}, guess, prior});
  EXPECT_FALSE(alone.verdict.trustworthy) << alone.verdict.reason;
  EXPECT_GT(error_of(alone, Isometry3::Identity()).translation_m, 0.5);  // why it needs a check
  const Summary checked = test::align_with(
      "adaptive", source, target,
      {{"init.prior_complete_search=check", "score.sharp_restart_share=0"}, guess, prior});
  EXPECT_TRUE(checked.verdict.trustworthy) << checked.verdict.reason;
  const TransformError e = error_of(checked, Isometry3::Identity());
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.1);
  bool rescued = false;
  for (const auto& [name, value] : checked.initialisation.notes) {
    rescued = rescued || name == "deeper pass after an untrusted answer";
  }
  EXPECT_TRUE(rescued);
}

}  // namespace
}  // namespace lmalign
