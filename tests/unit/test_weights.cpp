#include <cmath>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {
namespace {

TEST(CovarianceWeight, SpectralNormIsLargestEigenvalue) {
  Mat3 c;
  c << 2, 1, 0, 1, 2, 0, 0, 0, 1;  // eigenvalues 3, 1, 1
  EXPECT_DOUBLE_EQ(covariance_weight(c, CovarianceNorm::kSpectral), 1.0 / (1.0 + 3.0));
  EXPECT_DOUBLE_EQ(covariance_weight(c, CovarianceNorm::kFrobenius), 1.0 / (1.0 + std::sqrt(11.0)));
}

TEST(CovarianceWeight, DiagonalAndZero) {
  const Mat3 d = Vec3(1e-4, 4e-4, 2e-4).asDiagonal();
  EXPECT_DOUBLE_EQ(covariance_weight(d), 1.0 / (1.0 + 4e-4));
  EXPECT_DOUBLE_EQ(covariance_weight(Mat3::Zero()), 1.0);
}

Map two_frame_map() {
  Map map;
  Frame a;
  a.id = 7;
  a.p_world_camera = Vec3(3, 4, 0);  // 5 m from the origin
  Frame b;
  b.id = 9;
  b.p_world_camera = Vec3(0, 0, 2);  // 2 m from the origin
  map.frames = {a, b};
  Landmark l0;
  l0.id = 1;
  l0.p_world = Vec3::Zero();
  l0.cov_world_m2 = Vec3(1e-4, 4e-4, 2e-4).asDiagonal();
  l0.observations = {{7, 1, 2}, {9, 3, 4}};
  Landmark l1;
  l1.id = 2;
  l1.p_world = Vec3(0, 0, 1);
  l1.observations = {{9, 5, 6}, {9, 5, 6}, {7, 1, 1}};
  Landmark l2;  // no observations
  l2.id = 3;
  map.landmarks = {l0, l1, l2};
  return map;
}

TEST(ViewDirections, TheMeanUnitRayFromTheObservingCentresOrZero) {
  Map map = two_frame_map();
  // l0 at the origin, seen from (3, 4, 0) and (0, 0, 2): rays (-0.6, -0.8, 0) and (0, 0, -1).
  // l1 at (0, 0, 1), seen twice from (0, 0, 2) and once from (3, 4, 0): rays (0, 0, -1) twice
  // and (-3, -4, 1) / sqrt(26). l2: no observations.
  std::vector<Vec3> v = map.view_directions();
  ASSERT_EQ(v.size(), 3u);
  EXPECT_LT((v[0] - Vec3(-0.6, -0.8, -1.0).normalized()).norm(), 1e-12);
  const Vec3 sum1 = 2.0 * Vec3(0, 0, -1) + Vec3(-3, -4, 1) / std::sqrt(26.0);
  EXPECT_LT((v[1] - sum1.normalized()).norm(), 1e-12);
  EXPECT_EQ(v[2], Vec3::Zero());
  // Seen from opposite sides: the mean ray is shorter than kMinViewConcentration, the direction
  // unknown (zero). Seen from a camera at the landmark itself, or from an unknown frame: no ray.
  Frame c;
  c.id = 11;
  c.p_world_camera = Vec3(-3, -4, 0);
  map.frames.push_back(c);
  map.landmarks[0].observations = {{7, 1, 2}, {11, 1, 2}};
  map.landmarks[2].p_world = Vec3(0, 0, 2);
  map.landmarks[2].observations = {{9, 1, 1}, {12, 1, 1}};
  v = map.view_directions();
  EXPECT_EQ(v[0], Vec3::Zero());
  EXPECT_EQ(v[2], Vec3::Zero());
  // Every direction is unit or zero, and moves with the map: after transform_map, the rotated.
  const Isometry3 T = pose_from_xyz_rpy_deg(1, 2, 3, 10, -20, 30);
  const Map moved = transform_map(two_frame_map(), T);
  const std::vector<Vec3> before = two_frame_map().view_directions();
  const std::vector<Vec3> after = moved.view_directions();
  for (std::size_t i = 0; i < before.size(); ++i) {
    EXPECT_LT((after[i] - T.linear() * before[i]).norm(), 1e-12) << i;
  }
}

TEST(MeanDistanceWeight, HandComputed) {
  const Map map = two_frame_map();
  EXPECT_DOUBLE_EQ(mean_observation_distance_m(map.landmarks[0], map), 3.5);
  // (1 + 1 + sqrt(9 + 16 + 1)) / 3: a frame observing twice counts twice.
  const double d1 = (1.0 + 1.0 + std::sqrt(26.0)) / 3.0;
  EXPECT_DOUBLE_EQ(mean_observation_distance_m(map.landmarks[1], map), d1);
  const auto w = compute_weights(map, WeightKind::kMeanDistance);
  ASSERT_EQ(w.size(), 3u);
  EXPECT_DOUBLE_EQ(w[0], 1.0 / 4.5);
  EXPECT_DOUBLE_EQ(w[1], 1.0 / (1.0 + d1));
  EXPECT_EQ(w[2], 0.0);  // no observations, no confidence
}

TEST(Weights, ObservationsUniformCovariance) {
  const Map map = two_frame_map();
  EXPECT_EQ(compute_weights(map, WeightKind::kObservations), (std::vector<double>{2, 3, 0}));
  EXPECT_EQ(compute_weights(map, WeightKind::kUniform), (std::vector<double>{1, 1, 1}));
  const auto wc = compute_weights(map, WeightKind::kCovariance);
  EXPECT_DOUBLE_EQ(wc[0], 1.0 / (1.0 + 4e-4));
  EXPECT_DOUBLE_EQ(wc[1], 1.0);
  WeightOptions frob;
  frob.covariance_norm = CovarianceNorm::kFrobenius;
  EXPECT_DOUBLE_EQ(compute_weights(map, WeightKind::kCovariance, frob)[0],
                   1.0 / (1.0 + std::sqrt(1e-8 + 16e-8 + 4e-8)));
}

TEST(Weights, UnknownFrameThrows) {
  Map map = two_frame_map();
  map.landmarks[0].observations.push_back({42, 0, 0});
  try {
    compute_weights(map, WeightKind::kMeanDistance);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown frame 42"), std::string::npos) << e.what();
  }
}

TEST(Weights, NamesRoundTrip) {
  for (WeightKind k : {WeightKind::kUniform, WeightKind::kCovariance, WeightKind::kObservations,
                       WeightKind::kMeanDistance}) {
    EXPECT_EQ(parse_weight_kind(to_string(k)), k);
  }
  EXPECT_EQ(parse_weight_kind("none"), WeightKind::kUniform);
  EXPECT_THROW(parse_weight_kind("cov"), InvalidArgument);
  EXPECT_EQ(parse_covariance_norm("frobenius"), CovarianceNorm::kFrobenius);
  EXPECT_THROW(parse_covariance_norm("l1"), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
