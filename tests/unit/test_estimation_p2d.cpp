// The point-to-distribution Gauss-Newton solver (estimation_p2d.hpp) against known answers, and
// the p2d / robust_p2d strategies end to end on a seeded synthetic pair with partial overlap,
// outliers and anisotropic landmark noise drawn from the maps' own covariances.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <random>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/estimation_p2d.hpp"
#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/uncertainty.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

Correspondences identity_pairs(std::size_t n) {
  Correspondences c(n);
  for (std::size_t i = 0; i < n; ++i)
    c[i] = {static_cast<PointIndex>(i), static_cast<PointIndex>(i), 0.0};
  return c;
}

/// A random covariance with standard deviation `along_m` on a random axis and `across_m` across.
Mat3 needle_covariance(std::mt19937& rng, double along_m, double across_m) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 axis = Vec3(g(rng), g(rng), g(rng)).normalized();
  return (along_m * along_m - across_m * across_m) * axis * axis.transpose() +
         across_m * across_m * Mat3::Identity();
}

Vec3 draw(std::mt19937& rng, const Mat3& C) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::LLT<Mat3> llt(C);
  return llt.matrixL() * Vec3(g(rng), g(rng), g(rng));
}

double max_abs_diff(const Isometry3& a, const Isometry3& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

/// The solver on pairs i <-> i, from the identity, with up to 30 Gauss-Newton steps.
PointToDistributionResult solve_pairs_in_order(const Points3& src, const Points3& tgt,
                                               const std::vector<Mat3>& cs,
                                               const std::vector<Mat3>& ct) {
  PointToDistributionOptions o;
  o.max_iterations = 30;
  return estimate_point_to_distribution(src, tgt, identity_pairs(src.size()), cs, ct, nullptr, o);
}

TEST(PointToDistribution, RecoversAKnownTransformFromNoiseFreePairs) {
  const Points3 src = test::room_points(200, 3);
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.3, 0.0, 0.0, 4.0, -3.0, 10.0);
  // 10 deg about z, plus roll and pitch, 0.3 m: far from the identity start.
  const Points3 tgt = transform_points(T_true, src);
  std::mt19937 rng(5);
  std::vector<Mat3> cs, ct;
  for (std::size_t i = 0; i < src.size(); ++i) {
    cs.push_back(needle_covariance(rng, 0.03, 0.002));
    ct.push_back(needle_covariance(rng, 0.03, 0.002));
  }
  const PointToDistributionResult r = solve_pairs_in_order(src, tgt, cs, ct);
  EXPECT_FALSE(r.degenerate);
  EXPECT_LT(max_abs_diff(r.T_target_source, T_true), 1e-9);
  EXPECT_LT(r.chi2, 1e-12);
  EXPECT_LT(r.iterations, 30);  // the step tolerance stopped it
}

TEST(PointToDistribution, EqualsWeightedUmeyamaWithIdenticalIsotropicCovariances) {
  const Points3 src = test::room_points(300, 4);
  const Isometry3 T_true = pose_from_xyz_rpy_deg(-0.2, 0.1, 0.05, 2.0, 1.0, -8.0);
  std::mt19937 rng(6);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> u(0.1, 3.0);
  Points3 tgt;
  std::vector<double> w;
  for (const Vec3& p : src) {
    tgt.push_back(T_true * p + Vec3(noise(rng), noise(rng), noise(rng)));
    w.push_back(u(rng));
  }
  const Correspondences c = identity_pairs(src.size());
  const Isometry3 umeyama = estimate_rigid_transform(src, tgt, c, &w);
  // Identical isotropic covariances (any scale, plus the floor) make Omega a constant multiple
  // of I: the cost is the weighted point-to-point one.
  const std::vector<Mat3> cs(src.size(), 4e-4 * Mat3::Identity());
  const std::vector<Mat3> ct(src.size(), 1e-4 * Mat3::Identity());
  PointToDistributionOptions o;
  o.max_iterations = 50;
  const PointToDistributionResult r = estimate_point_to_distribution(src, tgt, c, cs, ct, &w, o);
  EXPECT_FALSE(r.degenerate);
  EXPECT_LT(max_abs_diff(r.T_target_source, umeyama), 1e-9);
  // Zero covariances: Omega = I / floor^2, the same minimiser.
  const std::vector<Mat3> zero(src.size(), Mat3::Zero());
  const PointToDistributionResult z =
      estimate_point_to_distribution(src, tgt, c, zero, zero, &w, o);
  EXPECT_LT(max_abs_diff(z.T_target_source, umeyama), 1e-9);
}

TEST(PointToDistribution, BeatsPointToPointUnderAnisotropicNoiseAndIsCalibrated) {
  // Needle-shaped landmark errors (2 cm along a random axis, 1 mm across) on both sides, drawn
  // from the covariances the solver is given: over seeded trials, the minimum-variance cost
  // must beat the isotropic one clearly, and its unscaled covariance must explain its errors.
  const int trials = 60;
  double err_p2d = 0.0, err_p2p = 0.0, nees_sum = 0.0;
  for (int t = 0; t < trials; ++t) {
    std::mt19937 rng(100 + t);
    const Points3 src_true = test::room_points(80, 200 + t);
    const Isometry3 T_true = pose_from_xyz_rpy_deg(0.1, -0.2, 0.0, 1.0, 2.0, 5.0);
    Points3 src, tgt;
    std::vector<Mat3> cs, ct;
    for (const Vec3& p : src_true) {
      const Mat3 Cs = needle_covariance(rng, 0.02, 0.001);
      const Mat3 Ct = needle_covariance(rng, 0.02, 0.001);
      src.push_back(p + draw(rng, Cs));
      tgt.push_back(T_true * p + draw(rng, Ct));
      cs.push_back(Cs);
      ct.push_back(Ct);
    }
    const Correspondences c = identity_pairs(src.size());
    PointToDistributionOptions o;
    o.max_iterations = 20;
    o.covariance_floor_m = 1e-4;
    const PointToDistributionResult r =
        estimate_point_to_distribution(src, tgt, c, cs, ct, nullptr, o);
    ASSERT_FALSE(r.degenerate);
    const Isometry3 p2p = estimate_rigid_transform(src, tgt, c);
    const Vec6 e = pose_error_twist(r.T_target_source, T_true);
    err_p2d += e.head<3>().norm() + 0.5 * e.tail<3>().norm();  // metres + rad * 0.5 m lever
    const Vec6 e2 = pose_error_twist(p2p, T_true);
    err_p2p += e2.head<3>().norm() + 0.5 * e2.tail<3>().norm();
    PoseCovariance pc;
    pc.covariance = r.covariance;
    pc.valid = true;
    nees_sum += nees(e, pc);
    EXPECT_GT(r.variance_factor, 0.5) << t;
    EXPECT_LT(r.variance_factor, 1.6) << t;
  }
  err_p2d /= trials;
  err_p2p /= trials;
  EXPECT_LT(err_p2d, 0.6 * err_p2p) << "p2d " << err_p2d << " p2p " << err_p2p;
  const double mean_nees = nees_sum / trials;  // 6 when calibrated; chi2_6 mean over 60 trials
  EXPECT_GT(mean_nees, 4.0);
  EXPECT_LT(mean_nees, 8.5);
}

TEST(PointToDistribution, HugeVariancesCarryNoInformationInsteadOfCorruptingTheEstimate) {
  // Every tenth target landmark has a needle covariance of 1e7 m along a random axis (1e14 m^2:
  // a valid covariance for the map reader, e.g. a landmark seen without parallax) and lies
  // 1 m off its true place along that axis. Its information along the needle is ~1e-14 m^-2:
  // the noise-free pairs alone must give the truth. With Eigen's cofactor 3x3 inverse such a
  // pair's "information" (condition ~4e18) had no correct digit: the estimator returned
  // chi2 = NaN and a degenerate flag, at the start pose.
  const Points3 src = test::room_points(200, 3);
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.3, 0.0, 0.0, 4.0, -3.0, 10.0);
  Points3 tgt = transform_points(T_true, src);
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Mat3> cs, ct;
  for (std::size_t i = 0; i < src.size(); ++i) {
    cs.push_back(needle_covariance(rng, 0.03, 0.002));
    if (i % 10 == 0) {
      const Vec3 axis = Vec3(g(rng), g(rng), g(rng)).normalized();
      ct.push_back(1e14 * axis * axis.transpose() + 4e-6 * Mat3::Identity());
      tgt[i] += axis;
    } else {
      ct.push_back(needle_covariance(rng, 0.03, 0.002));
    }
  }
  const PointToDistributionResult r = solve_pairs_in_order(src, tgt, cs, ct);
  EXPECT_FALSE(r.degenerate);
  EXPECT_LT(max_abs_diff(r.T_target_source, T_true), 1e-7);
  EXPECT_GE(r.chi2, 0.0);
  EXPECT_LT(r.chi2, 1e-9);

  // Against the contract (PSD expected, only finiteness checked): covariances of -floor^2 I
  // cancel the floor, M = 0, which has no inverse. Still no NaN, and the truth.
  const double floor_m = PointToDistributionOptions{}.covariance_floor_m;
  const std::vector<Mat3> zero(src.size(), Mat3::Zero());
  const std::vector<Mat3> cancelling(src.size(), -floor_m * floor_m * Mat3::Identity());
  const PointToDistributionResult z =
      solve_pairs_in_order(src, transform_points(T_true, src), zero, cancelling);
  EXPECT_TRUE(std::isfinite(z.chi2));
  EXPECT_TRUE(z.T_target_source.matrix().allFinite());
  EXPECT_TRUE(z.covariance.allFinite());
  EXPECT_LT(max_abs_diff(z.T_target_source, T_true), 1e-7);
}

TEST(PointToDistribution, DegenerateInputGivesAFiniteResultAndAFlag) {
  const Isometry3 T0 = pose_from_xyz_rpy_deg(0.1, 0, 0, 0, 0, 3);
  // Two pairs: too few.
  Points3 two{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  std::vector<Mat3> cov2(2, 1e-4 * Mat3::Identity());
  PointToDistributionResult r =
      estimate_point_to_distribution(two, two, identity_pairs(2), cov2, cov2, nullptr, {}, T0);
  EXPECT_TRUE(r.degenerate);
  EXPECT_EQ(r.T_target_source.matrix(), T0.matrix());
  EXPECT_EQ(r.covariance, Mat6::Zero());
  // Collinear points: the rotation about the line is free; H is singular.
  Points3 line;
  for (int i = 0; i < 10; ++i) line.emplace_back(0.1 * i, 0.2 * i, -0.05 * i);
  std::vector<Mat3> cov(line.size(), 1e-4 * Mat3::Identity());
  r = estimate_point_to_distribution(line, transform_points(T0, line), identity_pairs(line.size()),
                                     cov, cov);
  EXPECT_TRUE(r.degenerate);
  EXPECT_TRUE(r.T_target_source.matrix().allFinite());
  EXPECT_TRUE(r.covariance.allFinite());
  // No pairs at all.
  r = estimate_point_to_distribution(line, line, {}, cov, cov);
  EXPECT_TRUE(r.degenerate);
  EXPECT_TRUE(r.T_target_source.matrix().isIdentity());
}

TEST(PointToDistribution, RefusesInvalidInput) {
  const Points3 p = test::room_points(10, 1);
  const std::vector<Mat3> cov(p.size(), 1e-4 * Mat3::Identity());
  const Correspondences c = identity_pairs(p.size());
  const std::vector<Mat3> short_cov(3, Mat3::Identity());
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, short_cov, cov), InvalidArgument);
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, cov, short_cov), InvalidArgument);
  std::vector<Mat3> nan_cov = cov;
  nan_cov[2](0, 0) = std::nan("");
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, nan_cov, cov), InvalidArgument);
  const std::vector<double> neg(p.size(), -1.0), zero(p.size(), 0.0), few(2, 1.0);
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, cov, cov, &neg), InvalidArgument);
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, cov, cov, &zero), InvalidArgument);
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, cov, cov, &few), InvalidArgument);
  Correspondences bad = c;
  bad[0].target_index = 99;
  EXPECT_THROW(estimate_point_to_distribution(p, p, bad, cov, cov), InvalidArgument);
  PointToDistributionOptions o;
  std::string why;
  o.covariance_floor_m = 0.0;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("covariance_floor_m"), std::string::npos) << why;
  EXPECT_THROW(estimate_point_to_distribution(p, p, c, cov, cov, nullptr, o), InvalidArgument);
  // A floor whose square underflows (or whose inverse square overflows the normal equations)
  // would let zero covariances give Omega = 1/0: refused below a nanometre.
  o.covariance_floor_m = 1e-200;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("1e-09"), std::string::npos) << why;
  o.covariance_floor_m = 1e-9;
  EXPECT_TRUE(o.is_valid(&why)) << why;
  o = {};
  o.max_iterations = -1;
  EXPECT_FALSE(o.is_valid(&why));
}

// --- the strategies end to end ------------------------------------------------------------

/// One room seen by two maps: the target keeps x + y >= 1.2 m, the source x + y <= 5 m; each
/// landmark's error is drawn from its own map covariance (map_from_points: up to ~3 cm along a
/// random axis, 1 mm across), and 10% of the source are uniform outliers.
struct AnisotropicScene {
  Points3 source;
  std::vector<Mat3> source_cov;  // source frame
  Map target;
  Isometry3 T_true;
};

AnisotropicScene make_anisotropic_scene(std::uint32_t seed) {
  const Points3 room = test::room_points(2500, seed);
  Points3 tgt_true, src_true;
  for (const Vec3& p : room) {
    if (p.x() + p.y() >= 1.2) tgt_true.push_back(p);
    if (p.x() + p.y() <= 5.0) src_true.push_back(p);
  }
  AnisotropicScene s;
  s.T_true = pose_from_xyz_rpy_deg(0.15, -0.1, 0.05, 3.0, -2.0, 12.0);
  s.target = test::map_from_points(tgt_true, seed + 2);
  std::mt19937 rng(seed + 1);
  for (Landmark& l : s.target.landmarks) l.p_world += draw(rng, l.cov_world_m2);
  const Map src_map = test::map_from_points(src_true, seed + 3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Mat3 Rinv = s.T_true.linear().transpose();
  for (const Landmark& l : src_map.landmarks) {
    Vec3 p = l.p_world + draw(rng, l.cov_world_m2);
    if (u(rng) < 0.1) p = Vec3(4.0 * u(rng), 3.0 * u(rng), 2.5 * u(rng));
    s.source.push_back(s.T_true.inverse() * p);
    s.source_cov.push_back(Rinv * l.cov_world_m2 * Rinv.transpose());
  }
  return s;
}

TEST(PointToDistributionStrategies, RecoverTheTruthWithOutliersAndPartialOverlap) {
  const AnisotropicScene s = make_anisotropic_scene(21);
  const PreparedTarget target(s.target);
  for (PaperStrategy st : {PaperStrategy::kP2D, PaperStrategy::kRobustP2D}) {
    const RobustRegistrationResult r = align_robust(s.source, target, robust_strategy_options(st),
                                                    Isometry3::Identity(), &s.source_cov);
    const TransformError e = transform_error(r.T_target_source, s.T_true);
    EXPECT_LT(e.rotation_deg, 0.2) << to_string(st);
    EXPECT_LT(e.translation_m, 0.005) << to_string(st);
    EXPECT_TRUE(r.converged) << to_string(st);
    EXPECT_EQ(r.final_max_distance_m, 0.05) << to_string(st);
    // The covariance comes from the P2D normal equations: symmetric positive definite.
    const Eigen::SelfAdjointEigenSolver<Mat6> eig(r.covariance);
    EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0) << to_string(st);
    EXPECT_LT(std::sqrt(r.covariance.topLeftCorner<3, 3>().diagonal().maxCoeff()), 2e-3);
  }
}

TEST(PointToDistributionStrategies, RefuseMissingCovariancesAndFourDof) {
  const AnisotropicScene s = make_anisotropic_scene(22);
  const PreparedTarget with(s.target);
  const PreparedTarget bare(s.target.positions());
  const RobustRegistrationOptions o = robust_strategy_options(PaperStrategy::kRobustP2D);
  EXPECT_EQ(o.cost, EstimationCost::kPointToDistribution);
  // No source covariances, wrong count, a target without covariances.
  EXPECT_THROW(align_robust(s.source, with, o), InvalidArgument);
  const std::vector<Mat3> few(3, Mat3::Identity());
  EXPECT_THROW(align_robust(s.source, with, o, Isometry3::Identity(), &few), InvalidArgument);
  EXPECT_THROW(align_robust(s.source, bare, o, Isometry3::Identity(), &s.source_cov),
               InvalidArgument);
  EXPECT_THROW(bare.covariances_m2(), InvalidArgument);
  // 4-DoF point-to-distribution is not implemented: refused by is_valid.
  RobustRegistrationOptions four = o;
  four.dof = DegreesOfFreedom::k4;
  std::string why;
  EXPECT_FALSE(four.is_valid(&why));
  EXPECT_NE(why.find("dof"), std::string::npos) << why;
  // Names round-trip.
  for (const char* n : {"point_to_point", "point_to_distribution"}) {
    EXPECT_EQ(to_string(parse_estimation_cost(n)), n);
  }
  EXPECT_EQ(parse_estimation_cost("p2d"), EstimationCost::kPointToDistribution);
  EXPECT_THROW(parse_estimation_cost("gicp"), InvalidArgument);
  EXPECT_EQ(parse_paper_strategy("p2d"), PaperStrategy::kP2D);
  EXPECT_EQ(parse_paper_strategy("robust_p2d"), PaperStrategy::kRobustP2D);
  // Point-to-point strategies ignore covariances: bit-identical with or without.
  const RobustRegistrationOptions p2p = robust_strategy_options(PaperStrategy::kRobustObs);
  const RobustRegistrationResult a = align_robust(s.source, with, p2p);
  const RobustRegistrationResult b =
      align_robust(s.source, with, p2p, Isometry3::Identity(), &s.source_cov);
  EXPECT_EQ(a.T_target_source.matrix(), b.T_target_source.matrix());
}

TEST(PointToDistributionStrategies, MahalanobisKernelAlsoRecoversTheTruth) {
  const AnisotropicScene s = make_anisotropic_scene(23);
  const PreparedTarget target(s.target);
  RobustRegistrationOptions o = robust_strategy_options(PaperStrategy::kRobustP2D);
  o.kernel_residual = KernelResidual::kMahalanobis;
  const RobustRegistrationResult r =
      align_robust(s.source, target, o, Isometry3::Identity(), &s.source_cov);
  const TransformError e = transform_error(r.T_target_source, s.T_true);
  EXPECT_LT(e.rotation_deg, 0.2);
  EXPECT_LT(e.translation_m, 0.005);
}

}  // namespace
}  // namespace lmalign
