// Merges of maps without metric scale (docs/merge.md, "Maps without metric scale"): the Sim(3)
// pose graph on synthetic similarity edges (every scale recovered; one metric map or a prior
// with a scale holds it; all-metric graphs stay the rigid graph bit for bit), and bad scales in
// manifests and ground truths refused in one line.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/merge/evaluation.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/merge/output.hpp"
#include "lmalign/merge/pose_graph.hpp"
#include "support/manifest_error.hpp"
#include "support/temp_dir.hpp"

namespace lmalign {
namespace {

// S_world_map with the given scale: a yaw of up to 180 deg, a few degrees of tilt, +-5 m.
Similarity3 random_similarity(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Similarity3{scale, pose_from_xyz_rpy_deg(5.0 * u(rng), 5.0 * u(rng), 0.5 * u(rng),
                                                  3.0 * u(rng), 3.0 * u(rng), 180.0 * u(rng))};
}

// Exp(xi) * S, xi = (rho, phi, sigma) drawn with the given sds: x -> e^sigma R(phi) x + rho.
Similarity3 perturbed(const Similarity3& S, std::mt19937_64& rng, double sd_t, double sd_r_rad,
                      double sd_log_scale) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 phi(sd_r_rad * g(rng), sd_r_rad * g(rng), sd_r_rad * g(rng));
  Similarity3 D;
  D.rigid.linear() =
      Eigen::AngleAxisd(phi.norm(), phi.norm() > 0 ? Vec3(phi.normalized()) : Vec3::UnitZ())
          .toRotationMatrix();
  D.rigid.translation() = Vec3(sd_t * g(rng), sd_t * g(rng), sd_t * g(rng));
  D.scale = std::exp(sd_log_scale * g(rng));
  return D * S;
}

// The edge S_j_i = S_wj^-1 S_wi measured with noise, as align_edge() reports a similarity.
Edge similarity_edge(std::size_t i, std::size_t j, const std::vector<Similarity3>& truth,
                     std::mt19937_64& rng, double sd_t = 0.005, double sd_r = 0.05 * kRadPerDeg,
                     double sd_log_scale = 0.002) {
  const Similarity3 S = perturbed(truth[j].inverse() * truth[i], rng, sd_t, sd_r, sd_log_scale);
  Edge e;
  e.source = i;
  e.target = j;
  e.T_target_source = S.rigid;
  e.scale_free = true;
  e.scale = S.scale;
  e.scale_sd = S.scale * sd_log_scale;
  e.covariance.setZero();
  e.covariance.diagonal() << sd_t * sd_t, sd_t * sd_t, sd_t * sd_t, sd_r * sd_r, sd_r * sd_r,
      sd_r * sd_r;
  Mat7 C = Mat7::Zero();
  C.topLeftCorner<6, 6>() = e.covariance;
  C(6, 6) = sd_log_scale * sd_log_scale;
  e.covariance_7x7 = C;
  e.covariance_valid = true;
  e.trusted = true;
  e.trust_reason = "ok";
  e.num_inliers = 100 + 10 * i + j;
  return e;
}

// Edges between neighbours and second neighbours on a loop of the maps (redundant).
std::vector<Edge> ring_edges(const std::vector<Similarity3>& truth, std::mt19937_64& rng) {
  std::vector<Edge> edges;
  const std::size_t n = truth.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t d : {1u, 2u}) {
      const std::size_t j = (i + d) % n;
      edges.push_back(similarity_edge(std::min(i, j), std::max(i, j), truth, rng));
    }
  }
  return edges;
}

std::vector<Similarity3> truths(const std::vector<double>& scales, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Similarity3> out;
  for (const double s : scales) out.push_back(random_similarity(rng, s));
  return out;
}

// Largest distance of the true map origins from the first one's (world units).
double extent_of(const std::vector<Similarity3>& truth) {
  double d = 0.0;
  for (const Similarity3& S : truth) {
    d = std::max(d, (S.rigid.translation() - truth[0].rigid.translation()).norm());
  }
  return d;
}

TEST(MergeSim3, RingOfSimilaritiesRecoversEveryScaleAndPose) {
  const std::vector<Similarity3> truth = truths({1.0, 0.3, 3.0, 0.5, 2.0, 1.7}, 21);
  std::mt19937_64 rng(22);
  const std::vector<Edge> edges = ring_edges(truth, rng);
  const std::size_t n = truth.size();
  const MergeResult r = solve_pose_graph(n, std::vector<std::optional<MapPrior>>(n), edges, {},
                                         std::vector<bool>(n, true));
  ASSERT_EQ(r.num_components, 1u);
  // The gauge: map 0's frame and scale.
  EXPECT_TRUE(r.maps[0].is_gauge);
  EXPECT_EQ(r.maps[0].scale, 1.0);
  EXPECT_FALSE(r.maps[0].scale_free);
  const double extent = extent_of(truth);
  for (std::size_t i = 1; i < n; ++i) {
    const Similarity3 S_true = truth[0].inverse() * truth[i];
    const SimilarityError err = similarity_error(r.maps[i].similarity(), S_true);
    EXPECT_LT(err.scale_error, 0.01) << i;
    EXPECT_LT(err.rotation_deg, 1.0) << i;
    EXPECT_LT(err.translation_m, 0.01 * extent) << i;
    EXPECT_TRUE(r.maps[i].scale_free) << i;
    EXPECT_GT(r.maps[i].scale_sd, 0.0) << i;
    EXPECT_LT(r.maps[i].scale_sd, 0.01 * r.maps[i].scale) << i;
  }
  // Every edge is right; at the 0.999 quantile of chi2(7) one of 12 may be rejected by chance
  // (this draw: edge 1 -> 2, chi2 22.7 at the truth itself).
  std::size_t rejected = 0;
  for (const EdgeReport& e : r.edges) rejected += e.rejected ? 1 : 0;
  EXPECT_LE(rejected, 1u);
  // The evaluation fits the part's own scale to the truth.
  const MergeEvaluation ev = evaluate_merge(r, edges, truth, {1.0, 0.01 * extent, 0.01});
  EXPECT_DOUBLE_EQ(ev.fraction_within, 1.0);
  EXPECT_DOUBLE_EQ(ev.pair_fraction_within, 1.0);
  EXPECT_LT(ev.max_scale_error, 0.01);
  EXPECT_LT(ev.max_pair_scale_error, 0.01);
  EXPECT_DOUBLE_EQ(ev.edge_precision, 1.0);
  // A wrong scale is seen: map 2 scaled by 1.05 after the fact is outside 1%.
  MergeResult wrong = r;
  wrong.maps[2].scale *= 1.05;
  const MergeEvaluation ev2 = evaluate_merge(wrong, edges, truth, {1.0, 1e3, 0.01});
  EXPECT_FALSE(ev2.maps[2].within);
  EXPECT_GT(ev2.max_pair_scale_error, 0.04);
}

TEST(MergeSim3, OneMetricMapFixesEveryScale) {
  // Map 2 has metric scale (world units per map unit 1); the others' scales are absolute then.
  const std::vector<Similarity3> truth = truths({0.4, 2.5, 1.0, 0.7, 1.9}, 31);
  std::mt19937_64 rng(32);
  const std::vector<Edge> edges = ring_edges(truth, rng);
  const std::size_t n = truth.size();
  std::vector<bool> free(n, true);
  free[2] = false;
  const MergeResult r =
      solve_pose_graph(n, std::vector<std::optional<MapPrior>>(n), edges, {}, free);
  EXPECT_EQ(r.maps[2].scale, 1.0);
  EXPECT_FALSE(r.maps[2].scale_free);
  EXPECT_TRUE(r.maps[0].is_gauge);
  EXPECT_TRUE(r.maps[0].scale_free);  // the gauge holds the frame, the metric map the scale
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_LT(std::abs(r.maps[i].scale / truth[i].scale - 1.0), 0.01)
        << i << ": " << r.maps[i].scale << " for " << truth[i].scale;
  }
}

TEST(MergeSim3, APriorWithAScaleHoldsItsMapsScale) {
  const std::vector<Similarity3> truth = truths({0.5, 2.2, 1.3, 0.35}, 41);
  std::mt19937_64 rng(42);
  const std::vector<Edge> edges = ring_edges(truth, rng);
  const std::size_t n = truth.size();
  std::vector<std::optional<MapPrior>> priors(n);
  MapPrior p;
  p.T_world_map = truth[1].rigid;
  p.covariance = Mat6::Identity() * 1e-4;
  p.scale = truth[1].scale;
  priors[1] = p;
  const MergeResult r = solve_pose_graph(n, priors, edges, {}, std::vector<bool>(n, true));
  EXPECT_EQ(r.maps[1].scale, truth[1].scale);
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_FALSE(r.maps[i].is_gauge) << i;
    const SimilarityError err = similarity_error(r.maps[i].similarity(), truth[i]);
    EXPECT_LT(err.scale_error, 0.01) << i;
    EXPECT_LT(err.rotation_deg, 1.0) << i;
    EXPECT_LT(err.translation_m, 0.1) << i;
  }
}

TEST(MergeSim3, AllMetricMapsGiveTheRigidGraphBitForBit) {
  // Rigid edges (scale 1): the flags all false are the graph without flags.
  std::vector<Similarity3> truth = truths({1, 1, 1, 1, 1, 1}, 51);
  std::mt19937_64 rng(52);
  std::vector<Edge> edges = ring_edges(truth, rng);
  for (Edge& e : edges) {
    e.scale_free = false;
    e.scale = 1.0;
    e.scale_sd = std::numeric_limits<double>::quiet_NaN();
    e.covariance_7x7.reset();
  }
  const std::vector<std::optional<MapPrior>> none(truth.size());
  const MergeResult a = solve_pose_graph(truth.size(), none, edges);
  const MergeResult b =
      solve_pose_graph(truth.size(), none, edges, {}, std::vector<bool>(truth.size(), false));
  for (std::size_t i = 0; i < truth.size(); ++i) {
    EXPECT_EQ(a.maps[i].T_world_map.matrix(), b.maps[i].T_world_map.matrix()) << i;
    EXPECT_EQ(a.maps[i].covariance, b.maps[i].covariance) << i;
    EXPECT_EQ(b.maps[i].scale, 1.0);
    EXPECT_FALSE(b.maps[i].scale_free);
  }
  EXPECT_EQ(a.final_chi2, b.final_chi2);
}

TEST(MergeSim3, AnEdgeWithAWrongScaleIsRejectedByTheCycleCheck) {
  const std::vector<Similarity3> truth = truths({1.0, 0.6, 2.4, 1.4, 0.8}, 61);
  std::mt19937_64 rng(62);
  std::vector<Edge> edges = ring_edges(truth, rng);
  // The weakest edge says 1.3 times the true scale.
  edges[3].scale *= 1.3;
  edges[3].num_inliers = 10;
  const std::size_t n = truth.size();
  const MergeResult r = solve_pose_graph(n, std::vector<std::optional<MapPrior>>(n), edges, {},
                                         std::vector<bool>(n, true));
  EXPECT_TRUE(r.edges[3].rejected);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (e != 3) EXPECT_FALSE(r.edges[e].rejected) << e;
  }
  const MergeEvaluation ev = evaluate_merge(r, edges, truth, {1.0, 0.1, 0.01});
  EXPECT_LT(ev.max_scale_error, 0.01);
  EXPECT_FALSE(ev.edge_true[3]);
}

TEST(MergeSim3, ManifestPriorsMayBeSimilaritiesWithAPositiveFiniteScale) {
  const Manifest m = parse_manifest(
      "maps:\n"
      "  - name: a\n"
      "    path: a.txt\n"
      "    T_world_map: [[0,-2,0,1],[2,0,0,0],[0,0,2,3],[0,0,0,1]]\n"
      "    prior_sigma: [2.0, 0.5]\n",
      "m.yaml", "/base");
  ASSERT_TRUE(m.maps[0].prior);
  EXPECT_NEAR(m.maps[0].prior->scale, 2.0, 1e-15);
  EXPECT_TRUE(is_rigid_transform(m.maps[0].prior->T_world_map));
  EXPECT_EQ(m.maps[0].prior->T_world_map.translation(), Vec3(1, 0, 3));
  // A reflection (negative determinant) and a non-finite entry: one line naming file and field.
  const std::string negative = test::manifest_error(
      "maps:\n  - {name: a, path: a.txt, T_world_map: [[-1,0,0,0],[0,-1,0,0],[0,0,-1,0],"
      "[0,0,0,1]], prior_sigma: [1, 1]}\n");
  EXPECT_NE(negative.find("m.yaml:2"), std::string::npos) << negative;
  EXPECT_NE(negative.find("maps[0].T_world_map: scale"), std::string::npos) << negative;
  EXPECT_NE(negative.find("expected finite and > 0"), std::string::npos) << negative;
  EXPECT_EQ(negative.find('\n'), std::string::npos);
  const std::string nan = test::manifest_error(
      "maps:\n  - {name: a, path: a.txt, T_world_map: [[.nan,0,0,0],[0,1,0,0],[0,0,1,0],"
      "[0,0,0,1]], prior_sigma: [1, 1]}\n");
  EXPECT_NE(nan.find("m.yaml:2"), std::string::npos) << nan;
  EXPECT_NE(nan.find("maps[0].T_world_map"), std::string::npos) << nan;
  EXPECT_EQ(nan.find('\n'), std::string::npos);
  // A prior built in code: the pose graph names the map and the field.
  MapPrior p;
  p.scale = std::numeric_limits<double>::quiet_NaN();
  try {
    solve_pose_graph(1, {p}, {}, {}, {true});
    ADD_FAILURE() << "a NaN prior scale was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("prior of map 0.scale"), std::string::npos) << e.what();
  }
}

TEST(MergeSim3, GroundTruthSimilaritiesAreReadAndBadScalesRefused) {
  test::ScratchDir dir("merge_sim3_truth");
  const std::string path = (std::filesystem::path(dir.path()) / "truth.yaml").string();
  std::ofstream(path) << "maps:\n  a: [[0,-3,0,1],[3,0,0,2],[0,0,3,0],[0,0,0,1]]\n"
                         "  b: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n";
  const std::vector<Similarity3> S = read_ground_truth_similarities(path, {"a", "b"});
  EXPECT_NEAR(S[0].scale, 3.0, 1e-15);
  EXPECT_EQ(S[1].scale, 1.0);
  EXPECT_THROW(read_ground_truth(path, {"a", "b"}), ParseError);  // the rigid reader refuses it
  for (const std::string& bad : {std::string("[[-2,0,0,0],[0,-2,0,0],[0,0,-2,0],[0,0,0,1]]"),
                                 std::string("[[.inf,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]"),
                                 std::string("[[0,0,0,0],[0,0,0,0],[0,0,0,0],[0,0,0,1]]")}) {
    std::ofstream(path) << "maps:\n  a: " << bad << "\n";
    try {
      read_ground_truth_similarities(path, {"a"});
      ADD_FAILURE() << bad << " was accepted";
    } catch (const ParseError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path + ":2"), std::string::npos) << what;
      EXPECT_NE(what.find("maps.a: scale"), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos);
    }
  }
}

TEST(MergeSim3, EdgeFileKeepsTheScale) {
  test::ScratchDir dir("merge_sim3_edge");
  const std::vector<Similarity3> truth = truths({0.5, 2.0}, 71);
  std::mt19937_64 rng(72);
  Edge e = similarity_edge(0, 1, truth, rng);
  e.key = "k";
  const std::string path = edge_file_path(dir.path(), "a", "b");
  write_edge_file(path, e);
  const std::optional<Edge> back = read_edge_file(path);
  ASSERT_TRUE(back);
  EXPECT_TRUE(back->scale_free);
  EXPECT_EQ(back->scale, e.scale);
  EXPECT_EQ(back->scale_sd, e.scale_sd);
  ASSERT_TRUE(back->covariance_7x7);
  EXPECT_EQ(*back->covariance_7x7, *e.covariance_7x7);
}

}  // namespace
}  // namespace lmalign
