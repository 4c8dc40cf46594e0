// Degenerate and hostile inputs to the registration (issue 5, docs/robustness.md): every case
// has a defined outcome, a clear error naming the problem or a result with a termination reason,
// and never a crash, a hang, or NaN/inf in the transform.
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/weights/weights.hpp"
#include "support/align_preset.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A finite, proper rigid transform: what every returned result must be.
void expect_proper_rigid(const Isometry3& T) {
  ASSERT_TRUE(T.matrix().allFinite()) << T.matrix();
  const Mat3 R = T.linear();
  EXPECT_LT((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-12) << R;
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_EQ(T.matrix().row(3), Eigen::RowVector4d(0, 0, 0, 1));
}

/// A proper rigid result that converged within `rotation_deg` and `translation_m` of T_true.
void expect_converged_to(const RegistrationResult& r, const Isometry3& T_true, double rotation_deg,
                         double translation_m) {
  expect_proper_rigid(r.T_target_source);
  EXPECT_TRUE(r.converged) << to_string(r.termination);
  const TransformError e = transform_error(r.T_target_source, T_true);
  EXPECT_LT(e.rotation_deg, rotation_deg);
  EXPECT_LT(e.translation_m, translation_m);
}

/// A proper rigid result that stopped as degenerate, not converged.
void expect_degenerate(const RegistrationResult& r) {
  expect_proper_rigid(r.T_target_source);
  EXPECT_EQ(r.termination, TerminationReason::kDegenerate);
  EXPECT_FALSE(r.converged);
}

std::vector<WeightKind> strategies() { return all_weight_kinds(); }

/// A target of bare points with every weight kind set to 1 (so all four strategies run).
PreparedTarget bare_target(const Points3& points) {
  PreparedTarget target(points);
  for (WeightKind kind :
       {WeightKind::kCovariance, WeightKind::kObservations, WeightKind::kMeanDistance}) {
    target.set_weights(kind, std::vector<double>(points.size(), 1.0));
  }
  return target;
}

/// The paper's strategy of a confidence on bare points, as every front end runs it
/// (align(preset), registration/presets.hpp).
RegistrationResult paper(const Points3& source, const PreparedTarget& target,
                         WeightKind weight = WeightKind::kUniform, const test::Ask& ask = {}) {
  return test::align_with(test::paper_preset(weight), source, target, ask).registration;
}

test::Ask at(const Isometry3& guess) {
  test::Ask a;
  a.initial_guess = guess;
  return a;
}

test::Ask with_k(int k) {
  test::Ask a;
  a.k = k;
  return a;
}

Correspondences identity_pairs(std::size_t n) {
  Correspondences c(n);
  for (std::size_t i = 0; i < n; ++i) c[i] = {PointIndex(i), PointIndex(i), 0.0};
  return c;
}

// ---------------------------------------------------------------------------------------------
// Empty and tiny maps

TEST(DegenerateMaps, EmptySourceOrTargetIsRefusedNamingWhich) {
  const Points3 some = test::room_points(20, 1);
  const PreparedTarget target = bare_target(some);
  try {
    paper(Points3{}, target, WeightKind::kUniform);
    FAIL() << "empty source accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("source has no landmarks"), std::string::npos) << e.what();
  }
  const PreparedTarget empty_target(Points3{});
  try {
    paper(some, empty_target, WeightKind::kUniform);
    FAIL() << "empty target accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("target has no landmarks"), std::string::npos) << e.what();
  }
  // An empty Map is a valid map; aligning it is the same refusal.
  const Map empty;
  EXPECT_THROW(test::align_with("base", SourceLandmarks::from_map(empty),
                                PreparedTarget(test::map_from_points(some, 2))),
               InvalidArgument);
}

TEST(DegenerateMaps, OneOrTwoSourceLandmarksStopWithNoCorrespondences) {
  const Points3 target_points = test::room_points(200, 3);
  const PreparedTarget target = bare_target(target_points);
  const Isometry3 init = pose_from_xyz_rpy_deg(0.1, 0, 0, 0, 0, 5);
  for (std::size_t n : {1u, 2u}) {
    const Points3 source(target_points.begin(), target_points.begin() + n);
    for (WeightKind s : strategies()) {
      SCOPED_TRACE(std::to_string(n) + " landmarks, " + to_string(s));
      const RegistrationResult r = paper(source, target, s, at(init));
      EXPECT_EQ(r.termination, TerminationReason::kNoCorrespondences);
      EXPECT_FALSE(r.converged);
      EXPECT_EQ(r.iterations, 0);
      EXPECT_EQ(r.num_correspondences, n);
      EXPECT_TRUE(r.T_target_source.matrix() == init.matrix());
      EXPECT_TRUE(std::isfinite(r.final_score_m2));
    }
  }
}

TEST(DegenerateMaps, ThreeLandmarksRecoverTheTransformExactly) {
  // A scalene triangle: three non-collinear points determine a rigid transform.
  const Points3 target_points = {Vec3(0, 0, 0), Vec3(1.0, 0.1, 0.05), Vec3(0.3, 0.8, -0.2)};
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.01, -0.02, 0.005, 0.5, -0.3, 1.0);
  const Points3 source = transform_points(T_true.inverse(), target_points);
  const PreparedTarget target = bare_target(target_points);
  for (WeightKind s : strategies()) {
    SCOPED_TRACE(to_string(s));
    const RegistrationResult r = paper(source, target, s);
    expect_converged_to(r, T_true, 1e-9, 1e-12);
  }
}

TEST(DegenerateMaps, OneOrTwoTargetLandmarksGiveADegenerateFiniteResult) {
  // Every source point pairs with the same target point (or one of two): the rotation is not
  // determined. The estimate keeps the smallest rotation and moves the centroid onto the target.
  const Points3 source = test::room_points(50, 5);
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : source) centroid += p;
  centroid /= static_cast<double>(source.size());

  const PreparedTarget one = bare_target({Vec3(10, -4, 2)});
  for (WeightKind s : strategies()) {
    SCOPED_TRACE("one target landmark, " + to_string(s));
    const RegistrationResult r = paper(source, one, s);
    expect_degenerate(r);
    EXPECT_TRUE(r.T_target_source.linear().isApprox(Mat3::Identity(), 1e-15));
    EXPECT_LT((r.T_target_source * centroid - Vec3(10, -4, 2)).norm(), 1e-12);
  }
  const PreparedTarget two = bare_target({Vec3(0, 0, 0), Vec3(1, 1, 0)});
  for (WeightKind s : strategies()) {
    SCOPED_TRACE("two target landmarks, " + to_string(s));
    const RegistrationResult r = paper(source, two, s);
    expect_degenerate(r);
  }
}

// ---------------------------------------------------------------------------------------------
// Collinear, coplanar, identical

TEST(DegenerateMaps, CollinearMapsGiveADegenerateResultOnTheTargetLine) {
  // Landmarks on one line: the rotation about the line is not observable.
  const Vec3 dir_t = Vec3(1, 2, 0.5).normalized();
  Points3 target_points;
  for (int i = 0; i < 40; ++i) target_points.push_back(Vec3(0.5, -1, 2) + 0.1 * i * dir_t);
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.02, 0.01, -0.01, 2, -1, 3);
  const Points3 source = transform_points(T_true.inverse(), target_points);
  const PreparedTarget target = bare_target(target_points);
  for (WeightKind s : strategies()) {
    SCOPED_TRACE(to_string(s));
    const RegistrationResult r = paper(source, target, s);
    expect_degenerate(r);
    // Whatever the spin about the line, every aligned source point lies on the target line.
    for (const Vec3& p : source) {
      const Vec3 q = r.T_target_source * p - Vec3(0.5, -1, 2);
      EXPECT_LT((q - q.dot(dir_t) * dir_t).norm(), 1e-9);
    }
  }
}

TEST(DegenerateMaps, CoplanarMapsAreWellDeterminedAndConverge) {
  // A floor only (z = 0): planar, but three non-collinear points fix a rotation.
  Points3 floor = test::room_points(3000, 9);
  for (Vec3& p : floor) p.z() = 0.0;
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.05, -0.03, 0.02, 1, -1, 3);
  const Points3 source =
      transform_points(T_true.inverse(), Points3(floor.begin(), floor.begin() + 2000));
  const PreparedTarget target = bare_target(floor);
  const RegistrationResult r = paper(source, target, WeightKind::kUniform);
  expect_converged_to(r, T_true, 1e-6, 1e-8);
}

TEST(DegenerateMaps, AllPointsIdenticalGiveThePureTranslation) {
  const Points3 source(30, Vec3(1, 2, 3));
  const PreparedTarget target = bare_target(Points3(25, Vec3(-4, 0.5, 7)));
  for (WeightKind s : strategies()) {
    SCOPED_TRACE(to_string(s));
    const RegistrationResult r = paper(source, target, s);
    expect_degenerate(r);
    EXPECT_TRUE(r.T_target_source.linear() == Mat3::Identity());
    EXPECT_LT((r.T_target_source.translation() - Vec3(-5, -1.5, 4)).norm(), 1e-12);
    EXPECT_EQ(r.final_score_m2, 0.0);
  }
}

TEST(DegenerateEstimation, ReportsTheRankAndStaysAProperRotation) {
  // Rank 0: identical points on one side.
  const Points3 same(5, Vec3(1, 1, 1));
  const Points3 spread = test::room_points(5, 11);
  EstimationReport report;
  Isometry3 T = estimate_rigid_transform(spread, same, identity_pairs(5), nullptr, &report);
  EXPECT_TRUE(report.degenerate);
  EXPECT_EQ(report.singular_values(0), 0.0);
  EXPECT_TRUE(T.linear() == Mat3::Identity());
  expect_proper_rigid(T);

  // Rank 1: collinear source and target; the result takes the source line onto the target line
  // with the smallest rotation.
  Points3 src, tgt;
  const Vec3 a = Vec3(1, 0, 0), b = Vec3(0, 0.6, 0.8);
  for (int i = 0; i < 10; ++i) {
    src.push_back(0.3 * i * a);
    tgt.push_back(Vec3(5, 5, 5) + 0.3 * i * b);
  }
  T = estimate_rigid_transform(src, tgt, identity_pairs(10), nullptr, &report);
  EXPECT_TRUE(report.degenerate);
  expect_proper_rigid(T);
  EXPECT_LT((T.linear() * a - b).norm(), 1e-12);
  EXPECT_NEAR(rotation_angle_deg(T.linear()), 90.0, 1e-9);  // the angle between a and b
  for (int i = 0; i < 10; ++i) EXPECT_LT((T * src[i] - tgt[i]).norm(), 1e-12);

  // Rank 2 (coplanar) is not degenerate.
  Points3 plane = test::room_points(20, 12);
  for (Vec3& p : plane) p.z() = 0.0;
  const Isometry3 T_true = pose_from_xyz_rpy_deg(0.3, 0.1, -0.2, 20, -10, 40);
  T = estimate_rigid_transform(plane, transform_points(T_true, plane), identity_pairs(20), nullptr,
                               &report);
  EXPECT_FALSE(report.degenerate);
  EXPECT_LT(transform_error(T, T_true).rotation_deg, 1e-9);
}

TEST(DegenerateEstimation, BadWeightsAndOverflowAreClearErrors) {
  const Points3 p = test::room_points(4, 13);
  const std::vector<double> negative = {1.0, -1.0, 1.0, 1.0};
  EXPECT_THROW(estimate_rigid_transform(p, p, identity_pairs(4), &negative), InvalidArgument);
  const std::vector<double> nan = {1.0, kNaN, 1.0, 1.0};
  EXPECT_THROW(estimate_rigid_transform(p, p, identity_pairs(4), &nan), InvalidArgument);
  Points3 huge = p;
  for (Vec3& q : huge) q *= 1e300;
  EXPECT_THROW(estimate_rigid_transform(huge, huge, identity_pairs(4)), InvalidArgument);
  // One huge side alone does not overflow: a finite answer.
  expect_proper_rigid(estimate_rigid_transform(huge, p, identity_pairs(4)));
}

// ---------------------------------------------------------------------------------------------
// Far from the origin, k, weights, distances

TEST(DegenerateMaps, CoordinatesAroundOneBillionMetresStayAccurate) {
  // Maps far from the origin (e.g. a global frame): the centred estimation keeps full precision.
  const Vec3 far(1e9, -1e9, 1e9);
  Points3 target_points = test::room_points(3000, 21);
  for (Vec3& p : target_points) p += far;
  // The true motion turns about a point of the map, as a real relocalisation would.
  const Isometry3 about_map = Eigen::Translation3d(far + Vec3(2, 1.5, 1)) *
                              pose_from_xyz_rpy_deg(0.05, -0.04, 0.02, 1, -1, 4) *
                              Eigen::Translation3d(-(far + Vec3(2, 1.5, 1)));
  const Points3 source = transform_points(
      about_map.inverse(), Points3(target_points.begin(), target_points.begin() + 2000));
  const PreparedTarget target = bare_target(target_points);
  const RegistrationResult r = paper(source, target, WeightKind::kUniform);
  expect_proper_rigid(r.T_target_source);
  EXPECT_TRUE(r.converged) << to_string(r.termination);
  // Double precision at 1e9 m is 1.2e-7 m; the errors are of that order.
  const TransformError e = transform_error(r.T_target_source, about_map);
  EXPECT_LT(e.rotation_deg, 1e-6);
  double worst_m = 0.0;
  for (const Vec3& p : source) {
    worst_m = std::max(worst_m, (r.T_target_source * p - about_map * p).norm());
  }
  EXPECT_LT(worst_m, 1e-5);
  EXPECT_LT(r.final_score_m2, 1e-10);
}

TEST(DegenerateMaps, CoordinatesBeyondTheSupportedRangeAreRefusedByTheEngine) {
  // align() of presets.hpp leaves such landmarks out (docs/robustness.md, "Supported range"); the
  // engine itself refuses them, naming the landmark.
  const Pipeline engine(find_preset("base").spec);
  const Points3 ok = test::room_points(10, 22);
  Points3 too_far = ok;
  too_far[7].y() = 2e15;
  SourceView far_view, ok_view;
  far_view.positions = &too_far;
  ok_view.positions = &ok;
  try {
    engine.run(far_view, bare_target(ok));
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("source landmark 7"), std::string::npos) << e.what();
  }
  try {
    engine.run(ok_view, bare_target(too_far));
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("target landmark 7"), std::string::npos) << e.what();
  }
  Isometry3 init = Isometry3::Identity();
  init.translation().x() = 1e300;
  EXPECT_THROW(paper(ok, bare_target(ok), WeightKind::kUniform, at(init)), InvalidArgument);
}

TEST(DegenerateMaps, KLargerThanTheTargetEqualsKEqualToTheTarget) {
  const Points3 target_points = test::room_points(12, 23);
  PreparedTarget target(target_points);
  std::vector<double> w(target_points.size());
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = 1.0 + static_cast<double>(i % 4);
  target.set_weights(WeightKind::kObservations, w);
  const Points3 source =
      transform_points(pose_from_xyz_rpy_deg(0.02, 0, 0, 0, 0, 2),
                       Points3(target_points.begin(), target_points.begin() + 8));
  const RegistrationResult all = paper(source, target, WeightKind::kObservations, with_k(12));
  const RegistrationResult more = paper(source, target, WeightKind::kObservations, with_k(4096));
  expect_proper_rigid(more.T_target_source);
  EXPECT_NE(more.termination, TerminationReason::kNotTerminated);
  EXPECT_TRUE(more.T_target_source.matrix() == all.T_target_source.matrix());
  EXPECT_EQ(more.iterations, all.iterations);
}

TEST(DegenerateMaps, AllTargetWeightsZeroMeansNoCorrespondences) {
  const Points3 target_points = test::room_points(100, 24);
  PreparedTarget target(target_points);
  target.set_weights(WeightKind::kObservations, std::vector<double>(target_points.size(), 0.0));
  const Isometry3 init = pose_from_xyz_rpy_deg(0, 0.1, 0, 0, 0, 0);
  const RegistrationResult r = paper(target_points, target, WeightKind::kObservations, at(init));
  EXPECT_EQ(r.termination, TerminationReason::kNoCorrespondences);
  EXPECT_EQ(r.num_correspondences, 0u);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_TRUE(r.T_target_source.matrix() == init.matrix());

  // The same from a map: landmarks without observations have w_obs = 0 and w_dist = 0.
  Map map = test::map_from_points(target_points, 25);
  for (Landmark& l : map.landmarks) l.observations.clear();
  const PreparedTarget from_map(map);
  for (WeightKind s : {WeightKind::kObservations, WeightKind::kMeanDistance}) {
    const RegistrationResult m = paper(target_points, from_map, s);
    EXPECT_EQ(m.termination, TerminationReason::kNoCorrespondences) << to_string(s);
  }
  // Base ignores weights and still aligns.
  const RegistrationResult base = paper(target_points, from_map, WeightKind::kUniform, at(init));
  EXPECT_TRUE(base.converged);
}

TEST(DegenerateMaps, MaxDistanceSoSmallThatNothingCorresponds) {
  const Points3 target_points = test::room_points(500, 26);
  const PreparedTarget target = bare_target(target_points);
  const Isometry3 init = pose_from_xyz_rpy_deg(0.01, 0, 0, 0, 0, 0);
  for (double d : {1e-9, 1e-150, std::numeric_limits<double>::denorm_min()}) {
    for (WeightKind s : strategies()) {
      test::Ask o = at(init);
      o.max_distance_m = d;
      const RegistrationResult r = paper(target_points, target, s, o);
      EXPECT_EQ(r.termination, TerminationReason::kNoCorrespondences) << d << " " << to_string(s);
      EXPECT_TRUE(r.T_target_source.matrix() == init.matrix());
    }
  }
}

TEST(DegenerateMaps, SourceEqualToTargetConvergesToTheIdentity) {
  const Points3 points = test::room_points(2000, 27);
  const Map map = test::map_from_points(points, 28);
  const PreparedTarget target(map);
  // Base ICP: every landmark pairs with itself, the identity, exactly.
  const RegistrationResult base = paper(map.positions(), target, WeightKind::kUniform);
  EXPECT_TRUE(base.converged) << to_string(base.termination);
  const TransformError e = transform_error(base.T_target_source, Isometry3::Identity());
  EXPECT_LT(e.rotation_deg, 1e-9);
  EXPECT_LT(e.translation_m, 1e-12);
  EXPECT_LT(base.final_score_m2, 1e-24);
  // Weighted-kNN (Eq. 6) pairs a landmark with its most trusted neighbour among the k nearest,
  // which is often another landmark: even a map aligned onto itself moves (docs/robustness.md).
  // The result is still a converged, finite transform near the identity.
  for (WeightKind s :
       {WeightKind::kCovariance, WeightKind::kObservations, WeightKind::kMeanDistance}) {
    SCOPED_TRACE(to_string(s));
    const RegistrationResult r = paper(map.positions(), target, s);
    expect_proper_rigid(r.T_target_source);
    EXPECT_TRUE(r.converged) << to_string(r.termination);
    EXPECT_LT(transform_error(r.T_target_source, Isometry3::Identity()).rotation_deg, 2.0);
    // With k = 1 the weighted strategies are base: the identity again.
    const RegistrationResult k1 = paper(map.positions(), target, s, with_k(1));
    EXPECT_LT(transform_error(k1.T_target_source, Isometry3::Identity()).translation_m, 1e-12);
  }
}

// ---------------------------------------------------------------------------------------------
// NaN and negative options

TEST(DegenerateOptions, NaNOrNegativeValuesAreRefusedNamingTheField) {
  // The paper's settings (the table's rows, presets.hpp): a value outside its bound names its
  // key; the request's k and limits likewise.
  const std::vector<std::string> bad_settings = {
      "match.k=-1",
      "match.k=0",
      "schedule.max_distance_m=nan",
      "schedule.max_distance_m=-0.5",
      "schedule.max_distance_m=0",
      "schedule.max_distance_m=-inf",
      "schedule.max_iterations=0",
      "schedule.max_iterations=-3",
      "schedule.transformation_epsilon_m2=nan",
      "schedule.transformation_epsilon_m2=-1e-9",
      "schedule.transformation_rotation_epsilon_cos=nan",
      "schedule.euclidean_fitness_epsilon=nan",
      "schedule.absolute_mse_epsilon_m2=nan",
      "schedule.max_iterations_similar_transforms=-1",
      "schedule.min_correspondences=2",
      "fitness.max_range_m=nan",
      "fitness.max_range_m=-1",
  };
  const Points3 points = test::room_points(50, 29);
  const PreparedTarget target = bare_target(points);
  for (const std::string& bad : bad_settings) {
    const std::string key = bad.substr(0, bad.find('='));
    try {
      paper(points, target, WeightKind::kObservations, {{bad}});
      ADD_FAILURE() << bad << " accepted";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << bad << ": " << e.what();
    }
  }
  for (const int k : {-1, 0}) {
    EXPECT_THROW(paper(points, target, WeightKind::kObservations, with_k(k)), InvalidArgument);
  }
  for (const double d : {kNaN, -0.5, 0.0, -kInf}) {
    test::Ask a;
    a.max_distance_m = d;
    try {
      paper(points, target, WeightKind::kObservations, a);
      ADD_FAILURE() << "max distance " << d << " accepted";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("max_distance_m"), std::string::npos) << e.what();
    }
  }
  // NaN in the data or the initial guess is refused too, naming what.
  Points3 nan_source = points;
  nan_source[3].x() = kNaN;
  try {
    paper(nan_source, target, WeightKind::kUniform);
    ADD_FAILURE() << "NaN source point accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("source landmark 3"), std::string::npos) << e.what();
  }
  Isometry3 nan_init = Isometry3::Identity();
  nan_init(1, 1) = kNaN;
  EXPECT_THROW(paper(points, target, WeightKind::kUniform, at(nan_init)), InvalidArgument);
  PreparedTarget weights_target(points);
  std::vector<double> w(points.size(), 1.0);
  w[4] = -1.0;
  EXPECT_THROW(weights_target.set_weights(WeightKind::kObservations, w), InvalidArgument);
  w[4] = kNaN;
  EXPECT_THROW(weights_target.set_weights(WeightKind::kObservations, w), InvalidArgument);
}

TEST(DegenerateWeights, ExtremeCovariancesAndDistancesGiveFiniteWeights) {
  Map map;
  Frame far;
  far.id = 0;
  far.p_world_camera = Vec3(1.7e308, -1.7e308, 1e308);
  map.frames.push_back(far);
  Landmark big;
  big.id = 1;
  big.p_world = Vec3(-1.7e308, 1.7e308, 0);
  big.cov_world_m2 = 1.7e308 * Mat3::Identity();
  big.observations = {{0, 1, 1}, {0, 2, 2}};
  map.landmarks.push_back(big);
  for (WeightKind kind :
       {WeightKind::kCovariance, WeightKind::kObservations, WeightKind::kMeanDistance}) {
    for (CovarianceNorm norm : {CovarianceNorm::kSpectral, CovarianceNorm::kFrobenius}) {
      WeightOptions options;
      options.covariance_norm = norm;
      for (double w : compute_weights(map, kind, options)) {
        EXPECT_TRUE(std::isfinite(w) && w >= 0.0) << to_string(kind) << " " << w;
      }
    }
  }
}

}  // namespace
}  // namespace lmalign
