// lmalign::merge on synthetic data: manifest errors, candidate planning, the pose graph (noisy
// edges, a planted false edge, disconnected parts, gauge), outputs and the edge cache.
#include <gtest/gtest.h>

#include <cmath>

#include <filesystem>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/merge/candidates.hpp"
#include "lmalign/merge/evaluation.hpp"
#include "lmalign/merge/folds.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/merge/output.hpp"
#include "lmalign/merge/pose_graph.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "support/manifest_error.hpp"
#include "support/temp_dir.hpp"

namespace lmalign {
namespace {

TEST(MergeManifest, ParsesPathsPriorsAndSigma) {
  const Manifest m = parse_manifest(
      "maps:\n"
      "  - {name: a, path: a.txt}\n"
      "  - name: b\n"
      "    path: /abs/b.txt\n"
      "    session: s1\n"
      "    T_world_map: [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]\n"
      "    prior_sigma: [2.0, 0.5]\n",
      "m.yaml", "/base");
  ASSERT_EQ(m.maps.size(), 2u);
  EXPECT_EQ(m.maps[0].path, "/base/a.txt");
  EXPECT_FALSE(m.maps[0].prior);
  EXPECT_EQ(m.maps[1].path, "/abs/b.txt");
  EXPECT_EQ(m.maps[1].session, "s1");
  ASSERT_TRUE(m.maps[1].prior);
  EXPECT_DOUBLE_EQ(m.maps[1].prior->T_world_map.translation().y(), 2.0);
  EXPECT_DOUBLE_EQ(m.maps[1].prior->covariance(0, 0), 0.25);
  EXPECT_NEAR(m.maps[1].prior->covariance(5, 5), std::pow(2.0 * kRadPerDeg, 2), 1e-15);
}

TEST(MergeManifest, BadInputGivesOneLineErrorNamingTheField) {
  const std::string rigid = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
  struct Case {
    std::string yaml, expected;
  } cases[] = {
      {"", "empty manifest"},
      {"maps: []\n", "empty manifest"},
      {"maps:\n  - {name: a, path: a.txt}\n  - {name: a, path: b.txt}\n",
       "m.yaml:3: maps[1].name: duplicate map name 'a'"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],"
       " prior_sigma: [1, 1]}\n",
       "maps[0].T_world_map: not a rigid transform"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid +
           ", prior_covariance: [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],"
           "[0,0,0,0,1,0],[0,0,0,0,0,-1]]}\n",
       "maps[0].prior_covariance: not positive definite"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid +
           ", prior_covariance: [[1,0.5,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],"
           "[0,0,0,0,1,0],[0,0,0,0,0,1]]}\n",
       "maps[0].prior_covariance: not symmetric"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid + ", prior_sigma: [0, 1]}\n",
       "prior_sigma: both sigmas must be > 0"},
      {"maps:\n  - {name: a, path: a.txt, colour: red}\n", "unknown key 'colour'"},
      {"maps:\n  - {name: a}\n", "maps[0].path: missing"},
  };
  for (const Case& c : cases) {
    const std::string what = test::manifest_error(c.yaml);
    EXPECT_NE(what.find(c.expected), std::string::npos) << c.yaml << " -> " << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(MergeManifest, UnreadableMapNamesTheMapAndFile) {
  test::ScratchDir dir("merge_manifest");
  Manifest m = parse_manifest("maps:\n  - {name: lost, path: nowhere.txt}\n", "m.yaml", dir.path());
  try {
    load_manifest_maps(m);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("map 'lost'"), std::string::npos) << what;
    EXPECT_NE(what.find("nowhere.txt"), std::string::npos) << what;
  }
}

// A random 3-D scene; maps are discs of it around positions, in frames moved by known poses.
Map scene_map(const Points3& world, const Vec3& centre, double radius,
              const Isometry3& T_world_map) {
  Map m;
  const Isometry3 T_map_world = T_world_map.inverse();
  for (const Vec3& p : world) {
    if ((p - centre).head<2>().norm() > radius) continue;
    Landmark l;
    l.id = static_cast<Id>(m.landmarks.size());
    l.p_world = T_map_world * p;
    l.cov_world_m2 = Mat3::Identity() * 1e-4;
    m.landmarks.push_back(l);
  }
  return m;
}

Isometry3 random_pose(std::mt19937_64& rng, double max_t, double max_yaw_deg) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return pose_from_xyz_rpy_deg(max_t * u(rng), max_t * u(rng), 0.2 * u(rng), 0, 0,
                               max_yaw_deg * u(rng));
}

Isometry3 perturb(const Isometry3& T, std::mt19937_64& rng, double sd_t, double sd_r_rad) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 rho(sd_t * g(rng), sd_t * g(rng), sd_t * g(rng));
  const Vec3 phi(sd_r_rad * g(rng), sd_r_rad * g(rng), sd_r_rad * g(rng));
  Isometry3 D = Isometry3::Identity();
  D.linear() =
      Eigen::AngleAxisd(phi.norm(), phi.norm() > 0 ? Vec3(phi.normalized()) : Vec3::UnitZ())
          .toRotationMatrix();
  D.translation() = rho;
  return D * T;
}

Edge make_edge(std::size_t i, std::size_t j, const std::vector<Isometry3>& truth,
               std::mt19937_64& rng, double sd_t, double sd_r) {
  Edge e;
  e.source = i;
  e.target = j;
  e.T_target_source = perturb(truth[j].inverse() * truth[i], rng, sd_t, sd_r);
  e.covariance.setZero();
  e.covariance.diagonal() << sd_t * sd_t, sd_t * sd_t, sd_t * sd_t, sd_r * sd_r, sd_r * sd_r,
      sd_r * sd_r;
  e.covariance_valid = true;
  e.trusted = true;
  e.trust_reason = "ok";
  return e;
}

struct Ring {
  std::vector<Isometry3> truth;
  std::vector<Edge> edges;
};

// n poses on a loop, edges between neighbours and second neighbours (redundant).
Ring make_ring(std::size_t n, std::uint64_t seed, double sd_t = 0.01,
               double sd_r = 0.2 * kRadPerDeg) {
  std::mt19937_64 rng(seed);
  Ring r;
  for (std::size_t i = 0; i < n; ++i) r.truth.push_back(random_pose(rng, 5.0, 180.0));
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t d : {1u, 2u}) {
      const std::size_t j = (i + d) % n;
      r.edges.push_back(make_edge(std::min(i, j), std::max(i, j), r.truth, rng, sd_t, sd_r));
    }
  }
  return r;
}

/// A prior at each map's true pose with covariance sd2 I (6x6, rad^2 and m^2).
std::vector<std::optional<MapPrior>> true_priors(const std::vector<Isometry3>& truth, double sd2) {
  std::vector<std::optional<MapPrior>> priors(truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    MapPrior p;
    p.T_world_map = truth[i];
    p.covariance = Mat6::Identity() * sd2;
    priors[i] = p;
  }
  return priors;
}

TEST(MergePoseGraph, RecoversTruthFromNoisyEdgesWithGaugeAtFirstMap) {
  const Ring ring = make_ring(8, 11);
  const std::vector<std::optional<MapPrior>> none(8);
  const MergeResult r = solve_pose_graph(8, none, ring.edges);
  EXPECT_EQ(r.num_components, 1u);
  EXPECT_TRUE(r.maps[0].is_gauge);
  EXPECT_TRUE(r.maps[0].T_world_map.isApprox(Isometry3::Identity(), 1e-12));
  EXPECT_TRUE(r.maps[0].covariance.isZero());
  for (std::size_t i = 0; i < 8; ++i) {
    // The gauge: world = map 0's frame.
    const Isometry3 T_true = ring.truth[0].inverse() * ring.truth[i];
    const TransformError err = transform_error(r.maps[i].T_world_map, T_true);
    EXPECT_LT(err.translation_m, 0.05) << i;
    EXPECT_LT(err.rotation_deg, 0.5) << i;
    if (i > 0) {
      EXPECT_TRUE(r.maps[i].covariance_valid);
      EXPECT_GT(r.maps[i].covariance(0, 0), 0.0);
    }
  }
  for (const EdgeReport& e : r.edges) EXPECT_FALSE(e.rejected);
  EXPECT_GT(r.final_chi2, 0.0);
  // The evaluation agrees (whatever the gauge).
  // (A 0.2 deg rotation noise about the target's origin moves a map 7 m away by 2.5 cm.)
  const MergeEvaluation ev = evaluate_merge(r, ring.edges, ring.truth, {2.0, 0.2});
  EXPECT_DOUBLE_EQ(ev.fraction_within, 1.0);
  EXPECT_DOUBLE_EQ(ev.edge_precision, 1.0);
}

TEST(MergePoseGraph, PlantedFalseEdgeIsRejectedAndDoesNotBendTheGraph) {
  Ring ring = make_ring(8, 12);
  const std::vector<std::optional<MapPrior>> none(8);
  const MergeResult clean = solve_pose_graph(8, none, ring.edges);
  // A confident, wrong edge 0 -> 4: 2 m and 30 degrees off.
  Edge bad = ring.edges[0];
  bad.source = 0;
  bad.target = 4;
  bad.T_target_source =
      pose_from_xyz_rpy_deg(2.0, 0, 0, 0, 0, 30) * ring.truth[4].inverse() * ring.truth[0];
  ring.edges.push_back(bad);
  const MergeResult r = solve_pose_graph(8, none, ring.edges);
  EXPECT_TRUE(r.edges.back().rejected);
  EXPECT_TRUE(r.edges.back().used);
  for (std::size_t e = 0; e + 1 < r.edges.size(); ++e) EXPECT_FALSE(r.edges[e].rejected) << e;
  for (std::size_t i = 0; i < 8; ++i) {
    const TransformError d = transform_error(r.maps[i].T_world_map, clean.maps[i].T_world_map);
    EXPECT_LT(d.translation_m, 1e-6) << i;
  }
  const MergeEvaluation ev = evaluate_merge(r, ring.edges, ring.truth, {2.0, 0.2});
  EXPECT_EQ(ev.false_kept_edges, 0u);
  EXPECT_FALSE(ev.edge_true.back());
}

TEST(MergePoseGraph, DisconnectedPartsAreReportedEachInItsOwnFrame) {
  std::mt19937_64 rng(5);
  std::vector<Isometry3> truth;
  for (int i = 0; i < 6; ++i) truth.push_back(random_pose(rng, 5.0, 180.0));
  // {0, 1, 2} and {3, 4, 5}; one untrusted edge between them does not join them.
  std::vector<Edge> edges{
      make_edge(0, 1, truth, rng, 0.01, 0.003), make_edge(1, 2, truth, rng, 0.01, 0.003),
      make_edge(3, 4, truth, rng, 0.01, 0.003), make_edge(4, 5, truth, rng, 0.01, 0.003),
      make_edge(2, 3, truth, rng, 0.01, 0.003)};
  edges.back().trusted = false;
  edges.back().trust_reason = "ambiguous";
  const MergeResult r = solve_pose_graph(6, std::vector<std::optional<MapPrior>>(6), edges);
  EXPECT_EQ(r.num_components, 2u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(r.maps[i].component, 0u);
  for (int i = 3; i < 6; ++i) EXPECT_EQ(r.maps[i].component, 1u);
  EXPECT_TRUE(r.maps[0].is_gauge);
  EXPECT_TRUE(r.maps[3].is_gauge);
  EXPECT_TRUE(r.maps[3].T_world_map.isApprox(Isometry3::Identity(), 1e-12));
  EXPECT_FALSE(r.edges.back().used);
  EXPECT_NE(r.edges.back().skip_reason.find("ambiguous"), std::string::npos);
  const TransformError e5 = transform_error(r.maps[5].T_world_map, truth[3].inverse() * truth[5]);
  EXPECT_LT(e5.translation_m, 0.05);
  // Each part is right in its own frame, but only the first of the two largest is placed: the
  // other three maps are not in its frame. Pairs: the 3 + 3 within each part, of 15.
  const MergeEvaluation ev = evaluate_merge(r, edges, truth, {1.0, 0.1});
  EXPECT_EQ(ev.num_parts, 2u);
  EXPECT_EQ(ev.num_edge_parts, 2u);
  EXPECT_EQ(ev.largest_part, 3u);
  EXPECT_EQ(ev.placed, 3u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_TRUE(ev.maps[i].connected) << i;
    EXPECT_EQ(ev.maps[i].placed, i < 3) << i;
    EXPECT_EQ(ev.maps[i].within, i < 3) << i;
    EXPECT_LT(ev.maps[i].rotation_deg, 1.0) << i;  // measured in its own part's frame
  }
  EXPECT_DOUBLE_EQ(ev.fraction_within, 0.5);
  EXPECT_EQ(ev.pairs_within, 6u);
  EXPECT_DOUBLE_EQ(ev.pair_fraction_within, 6.0 / 15.0);
}

// A map that no kept edge reaches is alone in its part: its pose is arbitrary (the gauge of its
// own part), so it is neither placed nor within, and it has no error (it used to count as within).
TEST(MergeEvaluation, MapAloneInItsPartIsNotPlaced) {
  Ring ring = make_ring(5, 15);
  std::mt19937_64 rng(15);
  ring.truth.push_back(random_pose(rng, 5.0, 180.0));
  ring.edges.push_back(make_edge(4, 5, ring.truth, rng, 0.01, 0.003));
  ring.edges.back().trusted = false;
  const MergeResult r = solve_pose_graph(6, std::vector<std::optional<MapPrior>>(6), ring.edges);
  ASSERT_EQ(r.num_components, 2u);
  const MergeEvaluation ev = evaluate_merge(r, ring.edges, ring.truth, {2.0, 0.2});
  EXPECT_EQ(ev.num_parts, 2u);
  EXPECT_EQ(ev.largest_part, 5u);
  for (std::size_t i = 0; i < 5; ++i) EXPECT_TRUE(ev.maps[i].within) << i;
  EXPECT_FALSE(ev.maps[5].connected);
  EXPECT_FALSE(ev.maps[5].placed);
  EXPECT_FALSE(ev.maps[5].within);
  EXPECT_TRUE(std::isnan(ev.maps[5].rotation_deg));
  EXPECT_NEAR(ev.fraction_within, 5.0 / 6.0, 1e-12);
  EXPECT_EQ(ev.pairs_within, 10u);      // the ring's own pairs; none with the lone map
  EXPECT_LT(ev.max_rotation_deg, 2.0);  // the lone map's NaN left out
  // Every map alone: nothing placed at all.
  std::vector<Edge> none = ring.edges;
  for (Edge& e : none) e.trusted = false;
  const MergeResult apart = solve_pose_graph(6, std::vector<std::optional<MapPrior>>(6), none);
  const MergeEvaluation ev0 = evaluate_merge(apart, none, ring.truth, {2.0, 0.2});
  EXPECT_EQ(ev0.num_parts, 6u);
  EXPECT_EQ(ev0.num_edge_parts, 6u);
  EXPECT_EQ(ev0.placed, 0u);
  EXPECT_DOUBLE_EQ(ev0.fraction_within, 0.0);
  EXPECT_DOUBLE_EQ(ev0.pair_fraction_within, 0.0);
}

// Parts held by priors share the priors' frame: one fit for all of them. A map alone with a
// wrong prior is placed (by its prior) and reported outside; alone with a good prior, within.
TEST(MergeEvaluation, PartsHeldByPriorsShareOneFrame) {
  Ring ring = make_ring(5, 16);
  std::mt19937_64 rng(16);
  ring.truth.push_back(random_pose(rng, 5.0, 180.0));
  ring.truth.push_back(random_pose(rng, 5.0, 180.0));
  std::vector<std::optional<MapPrior>> priors = true_priors(ring.truth, 1e-4);
  priors[6]->T_world_map = pose_from_xyz_rpy_deg(0.5, 0, 0, 0, 0, 30) * ring.truth[6];
  const MergeResult r = solve_pose_graph(7, priors, ring.edges);  // maps 5 and 6: no edge
  ASSERT_EQ(r.num_components, 1u);  // the priors' frame holds them all
  const MergeEvaluation ev = evaluate_merge(r, ring.edges, ring.truth, {2.0, 0.2});
  EXPECT_EQ(ev.num_parts, 1u);
  EXPECT_EQ(ev.num_edge_parts, 3u);  // the ring, and each lone map
  for (std::size_t i = 0; i < 7; ++i) EXPECT_TRUE(ev.maps[i].placed) << i;
  EXPECT_FALSE(ev.maps[5].connected);
  EXPECT_TRUE(ev.maps[5].within);
  EXPECT_FALSE(ev.maps[6].within);
  EXPECT_NEAR(ev.maps[6].rotation_deg, 30.0, 1.0);
  EXPECT_NEAR(ev.fraction_within, 6.0 / 7.0, 1e-12);
  EXPECT_EQ(ev.pairs_within, 15u);  // the 6 right maps' pairs, across parts too
}

TEST(MergePoseGraph, PriorsHoldTheGaugeAndInvalidCovarianceIsSkipped) {
  Ring ring = make_ring(5, 13);
  std::vector<std::optional<MapPrior>> priors = true_priors(ring.truth, 1e-2);
  ring.edges[0].covariance.setZero();
  ring.edges[0].covariance_valid = false;
  const MergeResult r = solve_pose_graph(5, priors, ring.edges);
  EXPECT_FALSE(r.edges[0].used);
  EXPECT_EQ(r.edges[0].skip_reason, "invalid covariance");
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_FALSE(r.maps[i].is_gauge);
    EXPECT_LT(transform_error(r.maps[i].T_world_map, ring.truth[i]).translation_m, 0.05) << i;
  }
}

// A triangle 0-1-2 with a confident wrong edge 0 -> 2 (65 deg off, as a look-alike desk
// window): without priors any two of the three edges agree, so only their strength can say
// which goes. The wrong edge is listed first and has the fewest inliers.
TEST(MergePoseGraph, CycleCheckRejectsTheWeakestEdgeOfAnInconsistentCycle) {
  std::mt19937_64 rng(21);
  std::vector<Isometry3> truth;
  for (int i = 0; i < 3; ++i) truth.push_back(random_pose(rng, 3.0, 180.0));
  Edge wrong = make_edge(0, 2, truth, rng, 0.01, 0.003);
  wrong.T_target_source = pose_from_xyz_rpy_deg(0.5, 0.2, 0, 0, 0, 65) * wrong.T_target_source;
  wrong.num_inliers = 410;
  Edge e01 = make_edge(0, 1, truth, rng, 0.01, 0.003);
  e01.num_inliers = 445;
  Edge e12 = make_edge(1, 2, truth, rng, 0.01, 0.003);
  e12.num_inliers = 660;
  const std::vector<Edge> edges{wrong, e01, e12};
  const std::vector<std::optional<MapPrior>> none(3);
  const MergeResult r = solve_pose_graph(3, none, edges);
  EXPECT_TRUE(r.edges[0].rejected);
  EXPECT_NE(r.edges[0].reject_reason.find("cycle check"), std::string::npos);
  EXPECT_FALSE(r.edges[1].rejected);
  EXPECT_FALSE(r.edges[2].rejected);
  EXPECT_EQ(r.num_components, 1u);
  const MergeEvaluation ev = evaluate_merge(r, edges, truth, {1.0, 0.1});
  EXPECT_DOUBLE_EQ(ev.fraction_within, 1.0);
  EXPECT_EQ(ev.false_kept_edges, 0u);
  // The same edges with the strengths swapped: the wrong one is now the strongest and stays,
  // so the check is what decides (and a consistent cycle keeps all three).
  std::vector<Edge> swapped = edges;
  swapped[0].num_inliers = 900;
  const MergeResult s = solve_pose_graph(3, none, swapped);
  EXPECT_FALSE(s.edges[0].rejected);
  EXPECT_TRUE(s.edges[1].rejected || s.edges[2].rejected);
  std::vector<Edge> consistent = edges;
  consistent[0] = make_edge(0, 2, truth, rng, 0.01, 0.003);
  const MergeResult k = solve_pose_graph(3, none, consistent);
  for (const EdgeReport& e : k.edges) EXPECT_FALSE(e.rejected);
  // Off, the robust solve alone decides.
  PoseGraphOptions off;
  off.check_cycles = false;
  const MergeResult o = solve_pose_graph(3, none, edges, off);
  for (const EdgeReport& e : o.edges) EXPECT_TRUE(e.reject_reason.empty());
}

// One misplaced map in a component does not move the others' errors.
TEST(MergeEvaluation, OneMisplacedMapDoesNotMoveTheOthersErrors) {
  Ring ring = make_ring(6, 14);
  const std::vector<std::optional<MapPrior>> none(6);
  MergeResult r = solve_pose_graph(6, none, ring.edges);
  r.maps[5].T_world_map = pose_from_xyz_rpy_deg(1.5, 0, 0, 0, 0, 120) * r.maps[5].T_world_map;
  const MergeEvaluation ev = evaluate_merge(r, ring.edges, ring.truth, {2.0, 0.2});
  for (std::size_t i = 0; i < 5; ++i) EXPECT_TRUE(ev.maps[i].within) << i;
  EXPECT_FALSE(ev.maps[5].within);
  EXPECT_GT(ev.maps[5].rotation_deg, 100.0);
  EXPECT_NEAR(ev.fraction_within, 5.0 / 6.0, 1e-12);
  EXPECT_TRUE(ev.maps[5].placed);   // placed by the merge, wrongly
  EXPECT_EQ(ev.pairs_within, 10u);  // of 15: none of the 5 with the misplaced map
}

TEST(MergePoseGraph, Chi2QuantileMatchesTables) {
  EXPECT_NEAR(chi2_quantile(0.999, 6), 22.458, 0.01 * 22.458);
  EXPECT_NEAR(chi2_quantile(0.5, 6), 5.348, 0.05);
  EXPECT_NEAR(chi2_quantile(0.99, 3), 11.345, 0.15);
}

TEST(MergeCandidates, PriorsKeepOverlappingPairsOnlyAndAllPairsWithout) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  Points3 world;
  for (int k = 0; k < 4000; ++k) world.emplace_back(u(rng), u(rng), 0.1 * u(rng));
  // Three maps: 0 and 1 overlap, 2 is far away.
  const std::vector<Vec3> centres{{-10, 0, 0}, {-6, 0, 0}, {12, 10, 0}};
  std::vector<MapSummary> s;
  std::vector<std::optional<MapPrior>> priors;
  for (std::size_t i = 0; i < 3; ++i) {
    const Isometry3 T = random_pose(rng, 3.0, 180.0);
    const Map m = scene_map(world, centres[i], 4.0, T);
    s.push_back(summarise_map(m, {}, i + 1));
    MapPrior p;
    p.T_world_map = T;
    p.covariance = Mat6::Identity() * 1e-3;
    priors.push_back(p);
  }
  const auto with = plan_candidates(s, priors);
  ASSERT_EQ(with.size(), 1u);
  EXPECT_EQ(with[0].source, 0u);
  EXPECT_EQ(with[0].target, 1u);
  ASSERT_TRUE(with[0].initial_guess && with[0].prior);
  EXPECT_TRUE(
      with[0].initial_guess->isApprox(priors[1]->T_world_map.inverse() * priors[0]->T_world_map));
  // A merge of at most all_pairs_max_maps maps rescues an untrusted prior edge with the
  // complete search too (a merge without priors would align every pair fully anyway); a
  // larger one with the maps' first pass alone (issue 37, item 4).
  EXPECT_EQ(with[0].prior_complete_search, "rescue");
  CandidateOptions fleet;
  fleet.all_pairs_max_maps = 2;
  const auto planned_as_fleet = plan_candidates(s, priors, fleet);
  ASSERT_EQ(planned_as_fleet.size(), 1u);
  EXPECT_EQ(planned_as_fleet[0].prior_complete_search, "check");
  const auto without = plan_candidates(s, std::vector<std::optional<MapPrior>>(3));
  EXPECT_EQ(without.size(), 3u);
  CandidateOptions budget;
  budget.max_pairs = 2;
  EXPECT_EQ(plan_candidates(s, std::vector<std::optional<MapPrior>>(3), budget).size(), 2u);
}

TEST(MergeCandidates, PreFilterKeepsTheBestFewPerMap) {
  std::vector<MapSummary> s(20);
  for (std::size_t i = 0; i < 20; ++i) {
    s[i].descriptor.assign(8, static_cast<double>(i));  // neighbours in index are most similar
    s[i].radius_m = 1.0;
  }
  CandidateOptions o;
  o.keep_per_map = 2;
  const auto c = plan_candidates(s, std::vector<std::optional<MapPrior>>(20), o);
  EXPECT_LT(c.size(), 20u * 19u / 2u);
  for (const CandidatePair& p : c)
    EXPECT_LE(p.target - p.source, 2u) << p.source << " " << p.target;
  // every map keeps its nearest neighbour
  for (std::size_t i = 0; i + 1 < 20; ++i) {
    EXPECT_TRUE(std::any_of(c.begin(), c.end(), [&](const CandidatePair& p) {
      return p.source == i && p.target == i + 1;
    })) << i;
  }
}

// The manifest accepts rotations orthonormal to 1e-6 (is_rigid_transform). Composed, two such gave
// a relative prior off by more (1.1e-6 in the input the merge-manifest fuzzer found), which the
// edge's alignment then refused as an initial guess: the merge failed on a manifest it accepted.
TEST(MergeCandidates, TheRelativePriorOfNearlyRigidPriorsIsARotation) {
  const Isometry3 exact = pose_from_xyz_rpy_deg(1.0, 2.0, 0.5, 10.0, -20.0, 125.0);
  Isometry3 skewed = pose_from_xyz_rpy_deg(1.5, 2.0, 0.4, 12.0, -18.0, 120.0);
  Mat3 stretch = Mat3::Identity();
  stretch(0, 1) = stretch(1, 0) = 4e-7;  // R^T R - I of about 8e-7: accepted
  stretch(2, 2) += 3e-7;
  skewed.linear() = (skewed.linear() * stretch).eval();
  ASSERT_TRUE(is_rigid_transform(skewed));
  const Mat6 C = Mat6::Identity() * 1e-4;
  const MapPrior a{skewed, C}, b{exact, C};
  for (const auto& [source, target] : {std::pair{a, b}, std::pair{b, a}}) {
    const Isometry3 unprojected = target.T_world_map.inverse() * source.T_world_map;
    const Isometry3 T = relative_prior(source, target, nullptr);
    const Mat3 R = T.linear();
    EXPECT_LT((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_LT((T.matrix() - unprojected.matrix()).cwiseAbs().maxCoeff(), 1e-5);
  }
  // Exact rotations are left bit for bit as composed.
  const MapPrior c{pose_from_xyz_rpy_deg(0.2, 0.1, 0.0, 0.0, 0.0, 30.0), C};
  EXPECT_EQ(relative_prior(c, b, nullptr).matrix(),
            (b.T_world_map.inverse() * c.T_world_map).matrix());
}

TEST(MergeOutput, WritesPosesEdgesAndFusedMergedMap) {
  test::ScratchDir dir("merge_out");
  std::mt19937_64 rng(9);
  std::vector<Isometry3> truth{Isometry3::Identity(), random_pose(rng, 3.0, 90.0)};
  Points3 world;
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int k = 0; k < 50; ++k) world.emplace_back(u(rng), u(rng), u(rng));
  std::vector<Map> maps{scene_map(world, Vec3::Zero(), 10.0, truth[0]),
                        scene_map(world, Vec3::Zero(), 10.0, truth[1])};
  std::vector<Edge> edges{make_edge(0, 1, truth, rng, 1e-4, 1e-5)};
  const MergeResult r = solve_pose_graph(2, std::vector<std::optional<MapPrior>>(2), edges);
  write_merge_outputs(dir.path(), {"a", "b"}, {"s", "s"}, maps, edges, r);
  for (const char* f :
       {"poses.yaml", "poses.json", "edges.csv", "summary.json", "merged_map.txt"}) {
    EXPECT_TRUE(std::filesystem::exists(dir.file(f))) << f;
  }
  const Map merged = read_map(dir.file("merged_map.txt"), MapReadOptions{0});
  ASSERT_EQ(merged.landmarks.size(), 50u);  // same session, same ids: fused
  for (std::size_t k = 0; k < 50; ++k) {
    EXPECT_LT((merged.landmarks[k].p_world - world[k]).norm(), 1e-3);
    EXPECT_NEAR(merged.landmarks[k].cov_world_m2(0, 0), 0.5e-4, 1e-6);  // information summed
  }
  // Fused: map b added nothing; its centre (the median of its landmarks, in the world) is a's.
  auto poses_json = [&]() {
    std::ifstream in(dir.file("poses.json"));
    return nlohmann::json::parse(in);
  };
  nlohmann::json poses = poses_json();
  EXPECT_EQ(poses["maps"][0]["merged_landmarks"], nlohmann::json({0, 50}));
  EXPECT_EQ(poses["maps"][1]["merged_landmarks"], nlohmann::json({50, 50}));
  write_merge_outputs(dir.path(), {"a", "b"}, {"", ""}, maps, edges, r);
  EXPECT_EQ(read_map(dir.file("merged_map.txt"), MapReadOptions{0}).landmarks.size(), 100u);
  poses = poses_json();
  EXPECT_EQ(poses["maps"][1]["merged_landmarks"], nlohmann::json({50, 100}));
  std::vector<double> xs;
  for (const Vec3& p : world) xs.push_back(p.x());
  std::nth_element(xs.begin(), xs.begin() + 25, xs.end());
  for (int m = 0; m < 2; ++m) {  // each map's centre: the world's median, whatever its frame
    EXPECT_NEAR(poses["maps"][m]["landmark_centre_world"][0].get<double>(), xs[25], 1e-3) << m;
  }
  // No temporary file is left behind.
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
  }
}

// The report says why a map stands alone, and which maps hold the same landmarks (issue 37:
// "reports per part why a map stayed alone"; a map listed twice).
TEST(MergeOutput, SaysWhyAMapIsAloneAndWhichMapsAreTheSame) {
  test::ScratchDir dir("merge_notes");
  std::mt19937_64 rng(5);
  std::vector<Isometry3> truth;
  for (int i = 0; i < 5; ++i) truth.push_back(random_pose(rng, 3.0, 90.0));
  Points3 world;
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int k = 0; k < 40; ++k) world.emplace_back(u(rng), u(rng), u(rng));
  std::vector<Map> maps;
  for (int i = 0; i < 5; ++i) maps.push_back(scene_map(world, Vec3::Zero(), 10.0, truth[i]));
  maps[2] = maps[0];  // map 0 listed twice; no pair planned for it
  std::vector<Edge> edges{
      make_edge(0, 1, truth, rng, 1e-4, 1e-5), make_edge(3, 0, truth, rng, 1e-4, 1e-5),
      make_edge(3, 1, truth, rng, 1e-4, 1e-5), make_edge(4, 1, truth, rng, 1e-4, 1e-5)};
  edges[1].trusted = false;
  edges[1].trust_reason = "too few covariance-gated inliers (4 < 12)";
  edges[2].trusted = false;
  edges[2].trust_reason = "too few covariance-gated inliers (5 < 12)";
  edges[3].covariance_valid = false;  // trusted, but it cannot enter the graph
  const MergeResult r = solve_pose_graph(5, std::vector<std::optional<MapPrior>>(5), edges);
  ASSERT_EQ(r.num_components, 4u);
  const std::vector<MapNote> notes = map_notes(maps, edges, r);
  ASSERT_EQ(notes.size(), 5u);
  EXPECT_TRUE(notes[0].alone.empty());
  EXPECT_TRUE(notes[1].alone.empty());
  EXPECT_EQ(notes[2].alone, "no candidate pair");
  EXPECT_EQ(notes[3].alone,
            "none of its 2 pairs was trusted (1: too few covariance-gated inliers (4 < 12); 1: too "
            "few covariance-gated inliers (5 < 12))");
  EXPECT_EQ(notes[4].alone.rfind("its trusted pairs did not enter the graph", 0), 0u)
      << notes[4].alone;
  ASSERT_TRUE(notes[2].same_landmarks_as.has_value());
  EXPECT_EQ(*notes[2].same_landmarks_as, 0u);
  for (std::size_t i : {0u, 1u, 3u, 4u}) EXPECT_FALSE(notes[i].same_landmarks_as) << i;
  // summary.json carries both.
  write_merge_outputs(dir.path(), {"a", "b", "a_again", "c", "d"}, {"", "", "", "", ""}, maps,
                      edges, r);
  std::ifstream in(dir.file("summary.json"));
  const nlohmann::json summary = nlohmann::json::parse(in);
  ASSERT_EQ(summary["maps_alone"].size(), 3u);
  EXPECT_EQ(summary["maps_alone"][0]["name"], "a_again");
  EXPECT_EQ(summary["maps_alone"][0]["reason"], "no candidate pair");
  EXPECT_EQ(summary["same_landmarks"], nlohmann::json::array({{"a_again", "a"}}));
  EXPECT_THROW(map_notes(maps, {}, r), InvalidArgument);
}

TEST(MergeManifest, ValuesBeyondTheSupportedRangeNameTheLineAndField) {
  // docs/robustness.md, "Supported range": translations within 1e15 m, standard deviations in
  // [1e-9, 1e15] (m; degrees), as for `lmalign align`'s options. Before, a prior 1e308 m away
  // reached the pose graph and ended in SIGSEGV.
  const std::string rigid = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
  struct Case {
    std::string yaml, expected;
  } cases[] = {
      {"maps:\n  - {name: a, path: a.txt, T_world_map: [[1,0,0,1e308],[0,1,0,0],[0,0,1,0],"
       "[0,0,0,1]], prior_sigma: [2, 0.5]}\n",
       "m.yaml:2: maps[0].T_world_map: translation (1e+308, 0, 0) m is beyond the supported range "
       "(|coordinate| <= 1e+15 m)"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid + ", prior_sigma: [2, 1e-300]}\n",
       "m.yaml:2: maps[0].prior_sigma[1] (translation_m): 1e-300 m is outside the supported range "
       "of a standard deviation ([1e-09, 1e+15] m)"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid + ", prior_sigma: [1e20, 1]}\n",
       "maps[0].prior_sigma[0] (rotation_deg): 1e+20 degrees is outside"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid +
           ", prior_covariance: [[1e-20,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],"
           "[0,0,0,0,1,0],[0,0,0,0,0,1]]}\n",
       "maps[0].prior_covariance[0][0]: standard deviation: 1e-10 m is outside"},
      {"maps:\n  - {name: a, path: a.txt, T_world_map: " + rigid +
           ", prior_covariance: [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],"
           "[0,0,0,0,1,0],[0,0,0,0,0,1e300]]}\n",
       "maps[0].prior_covariance[5][5]: standard deviation: 1e+150 rad is outside"},
  };
  for (const Case& c : cases) {
    const std::string what = test::manifest_error(c.yaml);
    EXPECT_NE(what.find(c.expected), std::string::npos) << c.yaml << " -> " << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  // At the range's edges: accepted.
  EXPECT_EQ(test::manifest_error(
                "maps:\n  - {name: a, path: a.txt, T_world_map: [[1,0,0,1e15],[0,1,0,-1e15],"
                "[0,0,1,0],[0,0,0,1]], prior_sigma: [1e-9, 1e15]}\n"),
            "");
}

TEST(MergeCandidates, PriorsBeyondTheRangeAreRefusedAndPriorsBeyondItOfEachOtherPlanNoPair) {
  std::vector<MapSummary> s(2);
  for (MapSummary& m : s) m.radius_m = 2.0;
  MapPrior far;
  far.T_world_map.translation() = Vec3(0, 1e308, 0);
  MapPrior near;
  EXPECT_THROW(plan_candidates(s, {far, near}), InvalidArgument);
  EXPECT_THROW(solve_pose_graph(2, {far, near}, {}), InvalidArgument);
  Edge e;
  e.source = 0;
  e.target = 1;
  e.T_target_source.translation() = Vec3(-1e300, 0, 0);
  e.covariance = Mat6::Identity();
  e.covariance_valid = e.trusted = true;
  EXPECT_THROW(solve_pose_graph(2, {near, near}, {e}), InvalidArgument);
  // Both within the range, 2e15 m apart, sigmas wide enough to overlap: no candidate (the guess
  // would be beyond the range) rather than an edge that cannot be aligned.
  MapPrior a, b;
  a.T_world_map.translation() = Vec3(1e15, 0, 0);
  b.T_world_map.translation() = Vec3(-1e15, 0, 0);
  a.covariance.diagonal() << 1e30, 1e30, 1e30, 1.0, 1.0, 1.0;  // sigmas 1e15 m, 57 degrees
  b.covariance = a.covariance;
  EXPECT_TRUE(plan_candidates(s, {a, b}).empty());
  // The graph of such priors alone is finite.
  const MergeResult r = solve_pose_graph(2, {a, b}, {});
  for (const MapPose& p : r.maps) EXPECT_TRUE(p.T_world_map.matrix().allFinite());
}

TEST(MergeOutput, LandmarksBeyondTheRangeAreLeftOutOfTheMergedMapAndCounted) {
  std::mt19937_64 rng(11);
  Points3 world;
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int k = 0; k < 20; ++k) world.emplace_back(u(rng), u(rng), u(rng));
  std::vector<Map> maps{scene_map(world, Vec3::Zero(), 10.0, Isometry3::Identity())};
  maps[0].landmarks[4].p_world = Vec3(1e300, 0, 0);
  const MergeResult r = solve_pose_graph(1, std::vector<std::optional<MapPrior>>(1), {});
  std::size_t left_out = 0;
  const Map merged = merge_maps(maps, {""}, r, 0, {}, nullptr, &left_out);
  EXPECT_EQ(left_out, 1u);
  EXPECT_EQ(merged.landmarks.size(), 19u);
  for (const Landmark& l : merged.landmarks) EXPECT_TRUE(l.p_world.allFinite());
}

TEST(MergeOutput, EdgeFileRoundTripsExactly) {
  test::ScratchDir dir("merge_edge");
  std::mt19937_64 rng(10);
  std::vector<Isometry3> truth{random_pose(rng, 3.0, 90.0), random_pose(rng, 3.0, 90.0)};
  Edge e = make_edge(0, 1, truth, rng, 0.01, 0.01);
  e.key = "abc";
  e.num_inliers = 17;
  e.inlier_ratio = 0.123456789012345;
  const std::string path = edge_file_path(dir.path(), "a/b", "c");
  EXPECT_EQ(std::filesystem::path(path).filename().string(), "a_b__c.json");
  EXPECT_FALSE(read_edge_file(path));
  write_edge_file(path, e);
  const std::optional<Edge> back = read_edge_file(path);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->T_target_source.matrix(), e.T_target_source.matrix());
  EXPECT_EQ(back->covariance, e.covariance);
  EXPECT_EQ(back->key, "abc");
  EXPECT_EQ(back->inlier_ratio, e.inlier_ratio);
  std::ofstream(path) << "{\"key\": 1";
  EXPECT_THROW(read_edge_file(path), ParseError);
}

// A look-alike fold (docs/merge.md, "Folds the merge reports"). Maps 0-7 lie along a line, with
// true edges between neighbours and second neighbours (50 inliers each). Maps 5-7 also get false
// edges to maps 1-3 (300 inliers each), as a turned copy of that place would give: they put
// maps 5-7 moved by W (60 deg, 33 m). The cycle check keeps the stronger false edges and rejects
// the three true edges at the fold's border, each of which asks for W to be undone:
// suspected_folds reports one fold of those three edges, with W's angle. The merge itself is
// unchanged. Without the false edges, or with one rejected outlier alone, there is no fold.
TEST(MergeFolds, RejectedEdgesThatAgreeOnOneMotionAreReportedAsAFold) {
  std::mt19937_64 rng(8);
  std::vector<Isometry3> truth;
  for (int i = 0; i < 8; ++i) {
    truth.push_back(pose_from_xyz_rpy_deg(8.0 * i, 0.5 * i, 0.0, 0, 0, 20.0 * i));
  }
  Points3 world;
  std::uniform_real_distribution<double> ux(-6.0, 62.0), uy(-6.0, 6.0), uz(0.0, 3.0);
  for (int k = 0; k < 2000; ++k) world.emplace_back(ux(rng), uy(rng), uz(rng));
  std::vector<Map> maps;
  for (int i = 0; i < 8; ++i) {
    maps.push_back(scene_map(world, truth[i].translation(), 6.0, truth[i]));
    ASSERT_GT(maps.back().landmarks.size(), 50u) << i;
  }
  std::vector<Edge> edges;
  for (std::size_t i = 0; i < 8; ++i) {
    for (std::size_t d : {1u, 2u}) {
      if (i + d >= 8) continue;
      edges.push_back(make_edge(i, i + d, truth, rng, 0.01, 0.003));
      edges.back().num_inliers = 50;
    }
  }
  const std::size_t num_true = edges.size();
  const Isometry3 W = pose_from_xyz_rpy_deg(-32.0, 3.0, 0.0, 0, 0, 60.0);
  for (const auto& [f, a] :
       std::vector<std::pair<std::size_t, std::size_t>>{{5, 1}, {6, 2}, {7, 3}, {5, 2}, {6, 3}}) {
    Edge e = make_edge(f, a, truth, rng, 0.01, 0.003);
    e.T_target_source = truth[a].inverse() * W * truth[f];  // f placed at W X_f
    e.num_inliers = 300;
    edges.push_back(e);
  }
  const std::vector<std::optional<MapPrior>> none(8);
  const MergeResult r = solve_pose_graph(8, none, edges);
  ASSERT_EQ(r.num_components, 1u);
  std::vector<std::size_t> rejected;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (r.edges[e].rejected) rejected.push_back(e);
  }
  ASSERT_EQ(rejected.size(), 3u);  // the true edges 3-5, 4-5 and 4-6
  for (std::size_t e : rejected) EXPECT_LT(e, num_true) << e;
  const std::vector<SuspectedFold> folds = suspected_folds(maps, edges, r);
  ASSERT_EQ(folds.size(), 1u);
  const SuspectedFold& f = folds.front();
  EXPECT_EQ(f.edges.size(), 3u);
  EXPECT_EQ(f.maps, (std::vector<std::size_t>{3, 4, 5, 6}));
  EXPECT_NEAR(f.motion_deg, 60.0, 0.5);
  // W or its inverse, as the graph's gauge (map 0) holds the world frame of the truth.
  const Isometry3 got = f.S_world_moved.rigid;
  const double to_w = transform_error(got, W).translation_m;
  const double to_inverse = transform_error(got, W.inverse()).translation_m;
  EXPECT_LT(std::min(to_w, to_inverse), 0.5) << to_w << " " << to_inverse;
  EXPECT_GT(f.motion_m, 5.0);
  // summary.json carries it, by map names.
  test::ScratchDir dir("merge_folds");
  const std::vector<std::string> names{"m0", "m1", "m2", "m3", "m4", "m5", "m6", "m7"};
  write_merge_outputs(dir.path(), names, std::vector<std::string>(8), maps, edges, r);
  std::ifstream in(dir.file("summary.json"));
  const nlohmann::json summary = nlohmann::json::parse(in);
  ASSERT_EQ(summary["suspected_folds"].size(), 1u);
  EXPECT_EQ(summary["suspected_folds"][0]["maps"], nlohmann::json::array({"m3", "m4", "m5", "m6"}));
  EXPECT_EQ(summary["suspected_folds"][0]["component"], 0);
  EXPECT_EQ(summary["suspected_folds"][0]["edges"].size(), 3u);
  EXPECT_NEAR(summary["suspected_folds"][0]["motion_deg"].get<double>(), 60.0, 0.5);
  // The true edges alone: nothing rejected, no fold.
  const std::vector<Edge> clean(edges.begin(),
                                edges.begin() + static_cast<std::ptrdiff_t>(num_true));
  const MergeResult c = solve_pose_graph(8, none, clean);
  EXPECT_TRUE(suspected_folds(maps, clean, c).empty());
  // One rejected outlier is no fold: at least two edges must agree. (A false edge weaker than
  // the true ones is the one the cycle check rejects.)
  std::vector<Edge> one = clean;
  one.push_back(edges[num_true]);
  one.back().num_inliers = 10;
  const MergeResult o = solve_pose_graph(8, none, one);
  std::size_t rejected_one = 0;
  for (const EdgeReport& e : o.edges) rejected_one += e.rejected ? 1 : 0;
  ASSERT_EQ(rejected_one, 1u);
  EXPECT_TRUE(suspected_folds(maps, one, o).empty());
  // Bad options and sizes.
  FoldOptions bad;
  bad.min_edges = 1;
  EXPECT_THROW(suspected_folds(maps, edges, r, bad), InvalidArgument);
  bad = FoldOptions{};
  bad.tolerance = 0.0;
  EXPECT_THROW(suspected_folds(maps, edges, r, bad), InvalidArgument);
  EXPECT_THROW(suspected_folds(maps, clean, r), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
