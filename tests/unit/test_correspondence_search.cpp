// The correspondence search (registration/stages/correspondence_search.hpp): descriptors,
// matches, the covariance-aware consistency graph and its cliques, on seeded simulated streets;
// and the default, whose complete search refines its poses.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/transform.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/stages/correspondence_search.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/sim/fleet_sim.hpp"
#include "lmalign/sim/street_sim.hpp"
#include "support/align_preset.hpp"

namespace lmalign {
namespace {

// `lmalign simulate --scene street --overlap 0.25 --frames 30 --landmarks 3000 --transform
// 20,5,0,0,0,120 --seed SEED`: the pairs.
sim::SlamMapPair street(std::uint64_t seed) {
  sim::StreetSimOptions o;
  o.seed = seed;
  o.overlap = 0.25;
  o.window_frames = 30;
  o.num_landmarks = 3000;
  o.T_target_source = pose_from_xyz_rpy_deg(20.0, 5.0, 0.0, 0.0, 0.0, 120.0);
  return sim::simulate_street_pair(o);
}

struct Search {
  SourceLandmarks source;
  PreparedTarget target;
  CorrespondenceSearchInput input;
  explicit Search(const sim::SlamMapPair& pair)
      : source(SourceLandmarks::from_map(pair.source)), target(pair.target) {
    input.source.points = &source.positions;
    input.source.covariances_m2 = &source.covariances_m2;
    input.source.view_directions = &source.view_directions;
    input.target = &target;
    input.ups_source = {source.up.value_or(Vec3::UnitZ())};
    input.ups_target = {target.up_axis().value_or(Vec3::UnitZ())};
    input.floor_m = estimate_data_scales(source.positions, &source.covariances_m2).floor_m;
  }
};

bool near_truth(const CorrespondenceSearchResult& r, const Isometry3& truth) {
  for (const CorrespondenceHypothesis& h : r.hypotheses) {
    const TransformError e = transform_error(h.T_target_source, truth);
    if (e.rotation_deg < 5.0 && e.translation_m < 3.0) return true;
  }
  return false;
}

TEST(CorrespondenceSearch, OneOfItsPosesIsNearTheTruthOnAStreetAndTheRunRepeats) {
  // Measured on seeds 1-9 of the street (one pair of up axes, 32 poses): a pose within
  // 5 deg / 3 m of the truth on 7 of 9; on seed 5 it is the 15th by clique size, within the
  // default 16.
  const sim::SlamMapPair pair = street(5);
  const Search s(pair);
  const CorrespondenceSearchOptions o;
  const CorrespondenceSearchResult r = correspondence_search(s.input, o);
  EXPECT_GT(r.matches, 100u);
  EXPECT_GT(r.radius_m, 0.0);
  ASSERT_FALSE(r.hypotheses.empty());
  EXPECT_LE(r.hypotheses.size(), o.hypotheses);
  for (std::size_t i = 1; i < r.hypotheses.size(); ++i) {
    EXPECT_GE(r.hypotheses[i - 1].inliers, r.hypotheses[i].inliers);
    EXPECT_GE(r.hypotheses[i].inliers, o.min_inliers);
  }
  EXPECT_TRUE(near_truth(r, pair.T_target_source));
  // Deterministic, whatever the thread count.
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const CorrespondenceSearchResult again = correspondence_search(s.input, o);
  omp_set_num_threads(saved);
  ASSERT_EQ(again.hypotheses.size(), r.hypotheses.size());
  for (std::size_t i = 0; i < r.hypotheses.size(); ++i) {
    EXPECT_TRUE(again.hypotheses[i].T_target_source.matrix() ==
                r.hypotheses[i].T_target_source.matrix());
  }
}

TEST(CorrespondenceSearch, VagueLandmarksMatchNothing) {
  // Covariances far wider than the descriptor radius: no landmark can tell where the maps
  // meet, so there are no matches and no poses (and no crash).
  const sim::SlamMapPair pair = street(2);
  Search s(pair);
  std::vector<Mat3> vague(s.source.positions.size(), Mat3::Identity() * 1e4);
  s.input.source.covariances_m2 = &vague;
  const CorrespondenceSearchResult r = correspondence_search(s.input, {});
  EXPECT_EQ(r.matches, 0u);
  EXPECT_TRUE(r.hypotheses.empty());
}

TEST(CorrespondenceSearch, TinyMapsGiveNoPosesAndBadInputThrows) {
  Points3 three{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  Points3 two{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  const PreparedTarget target(three);
  CorrespondenceSearchInput in;
  in.source.points = &two;
  in.target = &target;
  in.ups_source = {Vec3::UnitZ()};
  in.ups_target = {Vec3::UnitZ()};
  in.floor_m = 0.01;
  EXPECT_TRUE(correspondence_search(in, {}).hypotheses.empty());
  in.source.points = &three;  // too sparse for a descriptor: no poses either
  EXPECT_TRUE(correspondence_search(in, {}).hypotheses.empty());
  CorrespondenceSearchOptions bad;
  bad.neighbours = 2;
  EXPECT_THROW(correspondence_search(in, bad), InvalidArgument);
  in.floor_m = 0.0;
  EXPECT_THROW(correspondence_search(in, {}), InvalidArgument);
  in.floor_m = 0.01;
  in.ups_target.clear();
  EXPECT_THROW(correspondence_search(in, {}), InvalidArgument);
}

TEST(CorrespondenceSearch, ScaleStepsAreCheckedAndRigidCliquesKeepScaleOne) {
  const sim::SlamMapPair pair = street(5);
  const Search s(pair);
  for (const CorrespondenceHypothesis& h : correspondence_search(s.input, {}).hypotheses) {
    EXPECT_EQ(h.scale, 1.0);
  }
  CorrespondenceSearchOptions bad;
  EXPECT_EQ(bad.scale_steps, 0);  // rigid unless asked
  bad.scale_steps = 6;
  bad.scale_ratio = 1.0;
  EXPECT_THROW(correspondence_search(s.input, bad), InvalidArgument);
  bad.scale_ratio = 1.12;
  bad.scale_steps = -1;
  EXPECT_THROW(correspondence_search(s.input, bad), InvalidArgument);
}

// The four maps of MergeFleet.FourMapsWithoutMetricScaleOnASim3PoseGraph's fleet (seed 11),
// each overlapping pair with its source's lengths times 1 / 1.6: the correspondences measure
// the scale where their evidence is decisive, and then the engine searches once, at the
// measured scale (no searches again at other scales). Measured (2026-11-25): decisive on 5 of
// the 6 overlapping pairs, each initial scale within 1% of the truth; 3 of them trusted and
// right; two pairs that share few landmarks end elsewhere, untrusted (5-6 gated inliers).
TEST(AdaptiveFleet, AFreeScaleIsMeasuredByTheCorrespondencesNotSearchedAgain) {
  sim::FleetSimOptions fo;
  fo.num_maps = 4;
  fo.seed = 11;
  const sim::FleetScene scene = sim::simulate_fleet(fo);
  const double truth = 1.6;  // target units per source unit
  std::size_t measured = 0, trusted = 0;
  for (const sim::FleetOverlap& ov : scene.overlaps) {
    const Map source_map =
        transform_map(scene.maps[ov.i], Similarity3{1.0 / truth, Isometry3::Identity()});
    const SourceLandmarks source = SourceLandmarks::from_map(source_map);
    const PreparedTarget target(scene.maps[ov.j]);
    const Isometry3 T_j_i = scene.T_world_map[ov.j].inverse() * scene.T_world_map[ov.i];
    AlignRequest request;
    request.scale = ScaleMode::kFree;
    const Summary s = align(find_preset("adaptive"), source.view(), target, request);
    const TransformError e = transform_error(s.registration.T_target_source, T_j_i);
    if (s.verdict.trustworthy) {
      ++trusted;
      EXPECT_LT(e.rotation_deg, 1.0) << ov.i << " -> " << ov.j;
      EXPECT_LT(e.translation_m, 0.1) << ov.i << " -> " << ov.j;
      EXPECT_LT(std::abs(s.scale.scale / truth - 1.0), 0.01) << ov.i << " -> " << ov.j;
    }
    if (!std::isfinite(s.scale.measured_factor)) continue;
    ++measured;
    EXPECT_LT(std::abs(s.scale.initial_scale / truth - 1.0), 0.03) << ov.i << " -> " << ov.j;
    EXPECT_EQ(s.scale.searches, 1);
  }
  EXPECT_GE(measured + 1, scene.overlaps.size());
  EXPECT_GE(trusted, 3u);
}

// The default on the street `seed`, checked to end at the truth (0.5 deg, 0.2 m), trusted.
Summary default_at_the_truth(std::uint64_t seed) {
  const sim::SlamMapPair pair = street(seed);
  const SourceLandmarks source = SourceLandmarks::from_map(pair.source);
  const PreparedTarget target(pair.target);
  const Summary s = test::align_with("adaptive", source, target, test::Ask{});
  const TransformError e = transform_error(s.registration.T_target_source, pair.T_target_source);
  EXPECT_LT(e.rotation_deg, 0.5) << "seed " << seed;
  EXPECT_LT(e.translation_m, 0.2) << "seed " << seed;
  EXPECT_TRUE(s.verdict.trustworthy) << "seed " << seed << ": " << s.verdict.reason;
  return s;
}

TEST(AdaptiveStreet, TheCorrespondencePosesFindAPairTheVoteMisses) {
  // Seed 5 of the street: without the correspondence poses the default ends 24 deg /
  // 49 m off (a search failure: refined from the truth the same maps score 364 against 296);
  // with them it ends at the truth, trusted.
  default_at_the_truth(5);
}

// The value of the initialiser's note `name`, or NaN when it has none.
double note(const Summary& s, const std::string& name) {
  for (const auto& [key, value] : s.initialisation.notes) {
    if (key == name) return value;
  }
  return std::nan("");
}

TEST(AdaptiveStreet, TheFirstPassAloneAnswersWhenTrustedAndTheCompleteSearchOtherwise) {
  // Seed 2 of the street: the correspondence poses alone give the truth, trusted, and
  // the vote never runs (measured 2026-11-25: 0.47 s against 1.80 s with the vote).
  {
    const Summary s = default_at_the_truth(2);
    EXPECT_GT(note(s, "first pass correspondence poses"), 0.0);
    EXPECT_EQ(note(s, "search candidates"), 0.0);  // no vote
    EXPECT_TRUE(std::isnan(note(s, "complete search after an untrusted first pass")));
  }
  // A street of 1,000 landmarks (seed 1) where the first pass's answer is not trusted: the
  // complete search runs, and its answer is the one without a first pass, bit for bit.
  sim::StreetSimOptions o;
  o.seed = 1;
  o.num_landmarks = 1000;
  o.T_target_source = pose_from_xyz_rpy_deg(20.0, 5.0, 0.0, 0.0, 0.0, 120.0);
  const sim::SlamMapPair pair = sim::simulate_street_pair(o);
  const SourceLandmarks source = SourceLandmarks::from_map(pair.source);
  const PreparedTarget target(pair.target);
  const Summary s = test::align_with("adaptive", source, target, test::Ask{});
  EXPECT_EQ(note(s, "complete search after an untrusted first pass"), 1.0);
  EXPECT_GT(note(s, "search candidates"), 0.0);  // the vote ran
  const Summary off =
      test::align_with("adaptive", source, target, test::Ask{{"search.first_pass=false"}});
  EXPECT_TRUE(std::isnan(note(off, "first pass correspondence poses")));
  EXPECT_TRUE(s.registration.T_target_source.matrix() == off.registration.T_target_source.matrix());
  EXPECT_EQ(s.verdict.trustworthy, off.verdict.trustworthy);
  EXPECT_EQ(s.verdict.reason, off.verdict.reason);
}

}  // namespace
}  // namespace lmalign
