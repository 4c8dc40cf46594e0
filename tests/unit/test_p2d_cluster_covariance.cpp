// The cluster-robust covariance of the adaptive pipeline's point-to-distribution estimate
// (stages/p2d_step.hpp, p2d_cluster_covariance) against the model covariance (p2d_covariance) on
// synthetic pairs whose landmark errors are correlated: every landmark of a spatial block shares
// one offset, which the landmark covariances do not know (as landmarks seen from the same frames
// share those frames' errors). NEES against the known truth over seeded trials.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include "lmalign/core/error.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "lmalign/registration/stages/p2d_step.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {
namespace {

struct TrialNees {
  double model = 0.0;    // p2d_covariance (s^2 H^-1)
  double cluster = 0.0;  // p2d_cluster_covariance
};

/// One trial: landmarks uniform in a 1 m cube; the target has independent noise sigma_point_m;
/// the source has the same plus one offset per cube block of edge block_edge_m (sd
/// sigma_block_m per axis). Both maps' covariances say sigma_point_m^2 I only. The estimate is
/// gated and solved from the truth (the identity) as the adaptive pipeline's final refinement.
TrialNees run_trial(std::uint64_t seed, double sigma_point_m, double sigma_block_m,
                    double block_edge_m) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::size_t n = 800;
  Points3 truth(n), source(n), target(n);
  std::map<std::tuple<int, int, int>, Vec3> offsets;
  for (std::size_t i = 0; i < n; ++i) {
    truth[i] = Vec3(u(rng), u(rng), u(rng));
    const auto key = std::make_tuple(static_cast<int>(truth[i].x() / block_edge_m),
                                     static_cast<int>(truth[i].y() / block_edge_m),
                                     static_cast<int>(truth[i].z() / block_edge_m));
    auto it = offsets.find(key);
    if (it == offsets.end())
      it = offsets.emplace(key, sigma_block_m * Vec3(g(rng), g(rng), g(rng))).first;
    source[i] = truth[i] + it->second + sigma_point_m * Vec3(g(rng), g(rng), g(rng));
    target[i] = truth[i] + sigma_point_m * Vec3(g(rng), g(rng), g(rng));
  }
  const std::vector<Mat3> cov(n, sigma_point_m * sigma_point_m * Mat3::Identity());
  PreparedTarget prepared(target);
  prepared.set_covariances(cov);
  GateSide side;
  side.points = &source;
  side.covariances_m2 = &cov;
  const MahalanobisGateOptions gate;
  const double floor_m = 0.1 * sigma_point_m;
  const Vec3 centre(0.5, 0.5, 0.5);
  Isometry3 T = Isometry3::Identity();
  std::vector<GatedPair> pairs;
  P2DStep step;
  PoseSigma sigma;
  for (int it = 0; it < 8; ++it) {
    sigma.pivot_m = T * centre;
    gate_correspondences(side, prepared, T, floor_m, sigma, gate, nullptr, &pairs);
    step = solve_p2d_step(pairs, prepared.points(), sigma.pivot_m,
                          cauchy_weights(pairs, gate.chi2_threshold));
    EXPECT_TRUE(step.ok);
    if (!step.ok) return {};
    if (it + 1 < 8) T = apply_step(T, step.xi, sigma.pivot_m);
  }
  // The last step was solved on `pairs` at T; the estimate is T moved by it.
  const Isometry3 T_est = apply_step(T, step.xi, sigma.pivot_m);
  const Vec6 e = pose_error_twist(T_est, Isometry3::Identity());
  const PoseCovariance model = p2d_covariance(step, pairs.size(), sigma.pivot_m);
  // Blocks of 0.25 m (about half the source's radius, as the adaptive pipeline sizes them), each
  // holding whole blocks of the simulated errors: the regime where a cluster-robust estimate
  // holds (errors shared across blocks would not be seen).
  const PoseCovariance cluster = p2d_cluster_covariance(
      pairs, prepared.points(), sigma.pivot_m, cauchy_weights(pairs, gate.chi2_threshold), 0.25);
  EXPECT_TRUE(model.valid);
  EXPECT_TRUE(cluster.valid);
  return {nees(e, model), nees(e, cluster)};
}

TEST(P2DClusterCovariance, NearerCalibrationThanTheModelWhenLandmarkErrorsAreCorrelatedByBlock) {
  const int trials = 50;
  double model = 0.0, cluster = 0.0;
  for (int t = 0; t < trials; ++t) {
    const TrialNees r = run_trial(7000 + t, 0.002, 0.002, 0.125);
    model += r.model;
    cluster += r.cluster;
  }
  model /= trials;
  cluster /= trials;
  RecordProperty("mean_nees_model", std::to_string(model));
  RecordProperty("mean_nees_cluster", std::to_string(cluster));
  // Within issue 21's band [3, 12] (6 = perfect), but NOT within the chi-square bounds of 50
  // trials ([4.46, 7.72]): measured 9.7, against 13.1 for the model covariance. With larger
  // shared offsets (3 and 4 mm) the sandwich stays too small (14.5 against 19.1 at 3 mm):
  // docs/accuracy.md, "Uncertainty of the adaptive default".
  EXPECT_GT(cluster, 3.0);
  EXPECT_LT(cluster, 12.0);
  // The model covariance, blind to the shared offsets, understates the error more.
  EXPECT_GT(model, 1.25 * cluster);
}

TEST(P2DClusterCovariance, IndependentErrorsKeepTheModelCovariance) {
  // Without shared offsets the model holds; the sandwich must not shrink it (never below the
  // model) nor inflate it much.
  const int trials = 50;
  double cluster = 0.0;
  for (int t = 0; t < trials; ++t) cluster += run_trial(9000 + t, 0.002, 0.0, 0.125).cluster;
  cluster /= trials;
  RecordProperty("mean_nees_cluster", std::to_string(cluster));
  EXPECT_GT(cluster, 3.0);
  EXPECT_LT(cluster, 7.72);
}

TEST(P2DClusterCovariance, DegenerateAndInvalidInput) {
  const Points3 target{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  std::vector<GatedPair> pairs(2);
  pairs[1].target_index = 1;
  pairs[1].moved_source_m = Vec3(1, 0, 0);
  for (GatedPair& p : pairs) p.information = Mat3::Identity();
  EXPECT_FALSE(p2d_cluster_covariance(pairs, target, Vec3::Zero(), cauchy_weights(pairs, 11.3), 0.5)
                   .valid);   // n < 3
  pairs.push_back(pairs[1]);  // three pairs on a line: singular
  EXPECT_FALSE(
      p2d_cluster_covariance(pairs, target, Vec3::Zero(), cauchy_weights(pairs, 11.3), 0.5).valid);
  EXPECT_THROW(
      p2d_cluster_covariance(pairs, target, Vec3::Zero(), cauchy_weights(pairs, 11.3), 0.0),
      InvalidArgument);
  EXPECT_THROW(
      p2d_cluster_covariance(pairs, target, Vec3::Zero(), cauchy_weights(pairs, 11.3), NAN),
      InvalidArgument);
}

}  // namespace
}  // namespace lmalign
