// triangulate(): DLT + Gauss-Newton + covariance (method.md §6), on seeded synthetic scenes.
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/triangulation.hpp"

namespace lmalign {
namespace {

// Camera at `centre` whose optical axis (+z) points at `target`, rolled by `roll` rad.
Isometry3 look_at(const Vec3& centre, const Vec3& target, double roll) {
  const Vec3 z = (target - centre).normalized();
  Vec3 helper = std::abs(z.y()) < 0.9 ? Vec3::UnitY() : Vec3::UnitX();
  const Vec3 x = helper.cross(z).normalized();
  const Vec3 y = z.cross(x);
  Mat3 R;  // columns: camera axes in world
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  R = R * Eigen::AngleAxisd(roll, Vec3::UnitZ()).toRotationMatrix();
  Isometry3 T = Isometry3::Identity();
  T.linear() = R;
  T.translation() = centre;
  return T;
}

PixelView view_of(const Isometry3& T_world_camera, const Vec3& p_world,
                  const PinholeIntrinsics& k) {
  const Eigen::Vector2d uv = k.project(T_world_camera.inverse() * p_world);
  return {T_world_camera, uv.x(), uv.y()};
}

// A random point and 2-6 cameras 1-4 m away around it, at least 15 degrees apart in direction
// from the point (good parallax), looking roughly at it (within ~5 degrees).
struct Scene {
  Vec3 p_world;
  std::vector<Isometry3> cameras;
};

Scene random_scene(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> distance(1.0, 4.0);
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  std::uniform_int_distribution<int> count(2, 6);
  Scene scene;
  scene.p_world = Vec3(unit(rng), unit(rng), unit(rng)) * 3.0;
  const int n = count(rng);
  const Vec3 mean_direction = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  std::vector<Vec3> directions;
  while (static_cast<int>(directions.size()) < n) {
    // Directions within a 60-degree cone around a common one, pairwise >= 15 degrees apart
    // for the first two (so the max parallax is >= ~15 degrees).
    const Vec3 d = (mean_direction + 0.6 * Vec3(unit(rng), unit(rng), unit(rng))).normalized();
    if (directions.size() == 1 &&
        std::acos(std::clamp(d.dot(directions[0]), -1.0, 1.0)) < 15.0 * kPi / 180.0) {
      continue;
    }
    directions.push_back(d);
  }
  for (const Vec3& d : directions) {
    const Vec3 centre = scene.p_world + distance(rng) * d;
    const Vec3 aim = scene.p_world + 0.1 * Vec3(unit(rng), unit(rng), unit(rng));
    scene.cameras.push_back(look_at(centre, aim, angle(rng)));
  }
  return scene;
}

TEST(Triangulation, NoiselessPixelsGiveTheExactPoint) {
  std::mt19937 rng(20240601);
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  for (int trial = 0; trial < 300; ++trial) {
    const Scene scene = random_scene(rng);
    std::vector<PixelView> views;
    for (const Isometry3& T : scene.cameras) views.push_back(view_of(T, scene.p_world, k));
    const auto point = triangulate(views);
    ASSERT_TRUE(point.has_value()) << "trial " << trial;
    EXPECT_LT((point->p_world - scene.p_world).norm(), 1e-9) << "trial " << trial;
    EXPECT_LT(point->rms_reprojection_px, 1e-6);
    EXPECT_GE(point->max_parallax_deg, 14.0);
    // The covariance is symmetric positive definite.
    EXPECT_LT((point->cov_world_m2 - point->cov_world_m2.transpose()).norm(), 1e-18);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat3>(point->cov_world_m2).eigenvalues()(0), 0.0);
  }
}

TEST(Triangulation, CovarianceIsConsistentWithOnePixelNoise) {
  // NEES = e^T Cov^-1 e of the error e against the returned covariance is chi^2(3) if the
  // covariance is right, so its mean over many points is near 3 (std of the mean ~0.11 for 500).
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  TriangulationOptions options;
  options.pixel_sigma_px = 1.0;
  const int kPoints = 500;
  double nees_sum = 0.0;
  int within_chi2_95 = 0;
  for (int i = 0; i < kPoints; ++i) {
    const Scene scene = random_scene(rng);
    std::vector<PixelView> views;
    for (const Isometry3& T : scene.cameras) {
      PixelView v = view_of(T, scene.p_world, k);
      v.u_px += noise(rng);
      v.v_px += noise(rng);
      views.push_back(v);
    }
    const auto point = triangulate(views, options);
    ASSERT_TRUE(point.has_value()) << "point " << i;
    const Vec3 e = point->p_world - scene.p_world;
    const double nees = e.dot(point->cov_world_m2.ldlt().solve(e));
    nees_sum += nees;
    if (nees < 7.815) ++within_chi2_95;  // chi^2(3) 95% quantile
  }
  const double mean_nees = nees_sum / kPoints;
  RecordProperty("mean_nees", std::to_string(mean_nees));
  RecordProperty("within_chi2_95", within_chi2_95);
  EXPECT_GE(mean_nees, 2.4);
  EXPECT_LE(mean_nees, 3.6);
  EXPECT_GE(within_chi2_95, static_cast<int>(0.90 * kPoints));
}

// A point pulled to a few centimetres from the cameras by an outlying pixel: J^T J then has a
// condition number just inside the accepted 1e12, where the 3x3 cofactor inverse returned a
// "covariance" with a negative diagonal (found by fuzz_map_reader through split with
// re-triangulation; the input is in fuzz/regressions/map_reader/). The covariance must stay
// symmetric positive semi-definite, as the map reader requires of every landmark.
TEST(Triangulation, CovarianceStaysPositiveDefiniteAtTheConditioningLimit) {
  auto pose = [](double tx, double ty, double tz, double qw, double qx, double qy, double qz) {
    Isometry3 T = Isometry3::Identity();
    T.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    T.translation() = Vec3(tx, ty, tz);
    return T;
  };
  const std::vector<PixelView> views = {
      {pose(1.311246, 0.850661, 1.518611, 0.390883167, -0.885094636, -0.236126904, 0.089788199),
       427329.198, 281.207306},
      {pose(1.345971, 0.818297, 1.530086, 0.403855533, -0.889981867, -0.192702611, 0.087742173),
       472.657104, 267.789551}};
  const auto r = triangulate(views);
  ASSERT_TRUE(r.has_value());
  const Mat3& C = r->cov_world_m2;
  EXPECT_TRUE(C.isApprox(C.transpose(), 0.0));
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(C);
  const Vec3 e = eig.eigenvalues();  // ascending
  ASSERT_GT(e(2), 0.0);
  EXPECT_GE(e(0), -1e-12 * e(2)) << e.transpose();
  for (int i = 0; i < 3; ++i) EXPECT_GT(C(i, i), 0.0) << i;
  // The case is at the limit (otherwise this test would prove nothing): the covariance spans
  // more than 10 orders of magnitude.
  EXPECT_GT(e(2), 1e10 * std::max(e(0), 1e-300)) << e.transpose();
}

TEST(Triangulation, CovarianceScalesWithSigmaSquared) {
  std::mt19937 rng(11);
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  const Scene scene = random_scene(rng);
  std::vector<PixelView> views;
  for (const Isometry3& T : scene.cameras) views.push_back(view_of(T, scene.p_world, k));
  TriangulationOptions one;
  TriangulationOptions two;
  two.pixel_sigma_px = 2.0;
  const auto a = triangulate(views, one);
  const auto b = triangulate(views, two);
  ASSERT_TRUE(a && b);
  EXPECT_LT((b->cov_world_m2 - 4.0 * a->cov_world_m2).norm(), 1e-12 * b->cov_world_m2.norm());
}

TEST(Triangulation, FewerThanTwoViewsGiveNothing) {
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  EXPECT_FALSE(triangulate({}).has_value());
  EXPECT_FALSE(triangulate({view_of(Isometry3::Identity(), Vec3(0, 0, 2), k)}).has_value());
}

TEST(Triangulation, PointBehindACameraGivesNothing) {
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  Isometry3 a = Isometry3::Identity();
  Isometry3 b = Isometry3::Identity();
  b.translation() = Vec3(1.0, 0.0, 0.0);
  // Behind both cameras (z = -2 in each); the pixel formula still gives finite pixels.
  const Vec3 behind(0.5, 0.2, -2.0);
  EXPECT_FALSE(triangulate({view_of(a, behind, k), view_of(b, behind, k)}).has_value());
  // In front of the first camera, behind the second (which sits at z = 3 looking along +z).
  Isometry3 c = Isometry3::Identity();
  c.translation() = Vec3(0.3, 0.0, 3.0);
  const Vec3 p(0.1, 0.1, 1.0);
  EXPECT_FALSE(triangulate({view_of(a, p, k), view_of(c, p, k)}).has_value());
  // Sanity: the same point from two cameras in front of it does triangulate.
  EXPECT_TRUE(triangulate({view_of(a, p, k), view_of(b, p, k)}).has_value());
}

TEST(Triangulation, ZeroParallaxIsRejected) {
  // Two views from the same centre: depth is unobservable, J^T J is singular.
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  const Isometry3 a = Isometry3::Identity();
  Isometry3 b = Isometry3::Identity();
  b.linear() = Eigen::AngleAxisd(0.1, Vec3::UnitY()).toRotationMatrix();
  const Vec3 p(0.1, 0.1, 2.0);
  EXPECT_FALSE(triangulate({view_of(a, p, k), view_of(b, p, k)}).has_value());
}

TEST(Triangulation, ParallaxOfAHandBuiltNinetyDegreePair) {
  // Cameras at x = -1 and x = +1 looking along +z; the point (0, 0, 1) is seen along the rays
  // (1, 0, 1) and (-1, 0, 1): 90 degrees apart.
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  Isometry3 a = Isometry3::Identity();
  a.translation() = Vec3(-1.0, 0.0, 0.0);
  Isometry3 b = Isometry3::Identity();
  b.translation() = Vec3(1.0, 0.0, 0.0);
  const Vec3 p(0.0, 0.0, 1.0);
  const PixelView va = view_of(a, p, k);
  EXPECT_DOUBLE_EQ(va.u_px, 517.3 + 318.6);  // x/z = 1 in camera a
  EXPECT_DOUBLE_EQ(va.v_px, 255.3);
  const auto point = triangulate({va, view_of(b, p, k)});
  ASSERT_TRUE(point.has_value());
  EXPECT_NEAR(point->max_parallax_deg, 90.0, 1e-9);
  EXPECT_LT((point->p_world - p).norm(), 1e-12);
  // A third camera on the axis at z = -1 sees the point along (0, 0, 1), 45 degrees from each of
  // the others; the max stays 90 degrees.
  Isometry3 c = Isometry3::Identity();
  c.translation() = Vec3(0.0, 0.0, -1.0);
  const auto three = triangulate({va, view_of(b, p, k), view_of(c, p, k)});
  ASSERT_TRUE(three.has_value());
  EXPECT_NEAR(three->max_parallax_deg, 90.0, 1e-9);
}

TEST(Triangulation, NonFiniteInputGivesNothing) {
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  Isometry3 b = Isometry3::Identity();
  b.translation() = Vec3(1.0, 0.0, 0.0);
  const Vec3 p(0.1, 0.1, 2.0);
  PixelView bad = view_of(b, p, k);
  bad.u_px = std::nan("");
  EXPECT_FALSE(triangulate({view_of(Isometry3::Identity(), p, k), bad}).has_value());
}

}  // namespace
}  // namespace lmalign
