// The camera model table (include/lmalign/map/camera_model.hpp) and triangulation from bearing
// vectors (make_bearing_view, triangulation.hpp): every model's projection and unprojection
// invert each other over its field of view, hand-computed values of the models' equations, and
// points triangulated through fisheye and equirectangular cameras (rays up to 180 degrees from
// the axis) with a covariance consistent with raw pixel noise.
#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/camera_model.hpp"
#include "lmalign/map/triangulation.hpp"

namespace lmalign {
namespace {

CameraIntrinsics camera(CameraModel model, std::vector<double> params) {
  CameraIntrinsics k;
  k.model = model;
  k.params = std::move(params);
  return k;
}

/// Realistic parameters of every model, and the largest angle from the optical axis the
/// round-trip test uses (degrees).
struct Case {
  CameraIntrinsics k;
  double max_angle_deg;
};
std::vector<Case> every_model() {
  using M = CameraModel;
  return {
      {camera(M::kSimplePinhole, {500, 320, 240}), 40},
      {camera(M::kPinhole, {500, 480, 320, 240}), 40},
      {camera(M::kSimpleRadial, {500, 320, 240, -0.1}), 35},
      {camera(M::kRadial, {500, 320, 240, -0.1, 0.02}), 35},
      {camera(M::kOpenCv, {500, 480, 320, 240, -0.1, 0.02, 0.001, -0.002}), 35},
      // The Intel T265's left fisheye (../shared/data/real_formats t265 cameras.txt).
      {camera(M::kOpenCvFisheye, {284.468, 285.51, 424.355, 393.742, 0.0008, 0.031, -0.03, 0.005}),
       100},
      {camera(M::kFullOpenCv,
              {500, 480, 320, 240, -0.1, 0.02, 0.001, -0.002, 0.001, 0.01, 0.001, 0.0001}),
       35},
      {camera(M::kFov, {500, 480, 320, 240, 0.9}), 50},
      {camera(M::kSimpleRadialFisheye, {300, 320, 240, 0.02}), 100},
      {camera(M::kRadialFisheye, {300, 320, 240, 0.02, -0.005}), 100},
      {camera(M::kThinPrismFisheye,
              {300, 305, 320, 240, 0.02, -0.005, 0.001, -0.001, 0.001, -0.0005, 0.0005, -0.0003}),
       90},
      {camera(M::kRadTanThinPrismFisheye,
              {300, 305, 320, 240, 0.02, -0.005, 0.001, -0.0005, 0.0001, -0.00001, 0.001, -0.001,
               0.0005, -0.0001, 0.0003, -0.00005}),
       90},
      {camera(M::kSimpleDivision, {500, 320, 240, -0.2}), 50},
      {camera(M::kDivision, {500, 480, 320, 240, -0.2}), 50},
      {camera(M::kSimpleFisheye, {300, 320, 240}), 150},
      {camera(M::kFisheye, {300, 310, 320, 240}), 150},
      {camera(M::kEucm, {400, 410, 320, 240, 0.6, 1.1}), 100},
      {camera(M::kEquirectangular, {1920, 960}), 179},
  };
}

/// A unit direction at most `max_angle_deg` from +z.
Vec3 random_direction(std::mt19937& rng, double max_angle_deg) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double theta = max_angle_deg * kPi / 180.0 * std::sqrt(unit(rng));
  const double phi = 2.0 * kPi * unit(rng);
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

TEST(CameraModelTable, EveryColmapModelOnceWithItsIdNameAndParameterNames) {
  const std::vector<CameraModelInfo>& models = camera_models();
  ASSERT_EQ(models.size(), 18u);  // COLMAP's ids 0-17
  std::set<std::string> names;
  for (std::size_t i = 0; i < models.size(); ++i) {
    const CameraModelInfo& m = models[i];
    EXPECT_EQ(m.id, static_cast<int>(i));
    EXPECT_EQ(static_cast<int>(m.model), m.id);
    EXPECT_TRUE(names.insert(m.name).second) << m.name;
    EXPECT_EQ(camera_model_from_name(m.name), m.model);
    EXPECT_EQ(camera_model_from_id(m.id), m.model);
    // The parameter names are as many as the parameters.
    const std::string params = m.params;
    EXPECT_EQ(static_cast<std::size_t>(std::count(params.begin(), params.end(), ',')) + 1,
              m.num_params)
        << m.name;
    EXPECT_NE(camera_model_list().find(std::string(m.name) + " (" + std::to_string(m.id) + ")"),
              std::string::npos);
  }
  for (const char* name :
       {"OPENCV_FISHEYE", "FULL_OPENCV", "FOV", "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE",
        "THIN_PRISM_FISHEYE", "RAD_TAN_THIN_PRISM_FISHEYE", "EQUIRECTANGULAR"}) {
    EXPECT_TRUE(camera_model_from_name(name).has_value()) << name;
  }
  EXPECT_FALSE(camera_model_from_name("opencv").has_value());  // names are case sensitive
  EXPECT_FALSE(camera_model_from_id(18).has_value());
  EXPECT_FALSE(camera_model_from_id(-1).has_value());
  EXPECT_EQ(every_model().size(), models.size());
}

// project(unproject(pixel)) is the pixel and unproject(project(ray)) the ray, for every model
// over its field of view; the parameters are valid.
TEST(CameraModelTable, ProjectionAndUnprojectionInvertEachOther) {
  std::mt19937 rng(26);
  for (const Case& c : every_model()) {
    SCOPED_TRACE(camera_model_name(c.k.model));
    std::string why;
    ASSERT_TRUE(c.k.is_valid(&why)) << why;
    double worst_ray = 0.0;
    double worst_px = 0.0;
    for (int i = 0; i < 400; ++i) {
      const Vec3 ray = random_direction(rng, c.max_angle_deg);
      const std::optional<Eigen::Vector2d> px = c.k.project_px(3.7 * ray);
      ASSERT_TRUE(px.has_value()) << ray.transpose();
      const std::optional<Vec3> back = c.k.unproject(px->x(), px->y());
      ASSERT_TRUE(back.has_value()) << ray.transpose() << " at " << px->transpose();
      EXPECT_NEAR(back->norm(), 1.0, 1e-12);
      worst_ray = std::max(worst_ray, (*back - ray).norm());
      const std::optional<Eigen::Vector2d> again = c.k.project_px(*back);
      ASSERT_TRUE(again.has_value());
      worst_px = std::max(worst_px, (*again - *px).norm());
    }
    EXPECT_LT(worst_ray, 1e-9);
    EXPECT_LT(worst_px, 1e-6);
  }
}

// Values computed by hand from the models' definitions.
TEST(CameraModelTable, HandComputedValues) {
  // Equirectangular 1920 x 960: longitude 2 pi (u / w - 1/2), latitude pi (1/2 - v / h); the
  // camera's x right, y down, z forward.
  const CameraIntrinsics eq = camera(CameraModel::kEquirectangular, {1920, 960});
  EXPECT_LT((*eq.unproject(960, 480) - Vec3(0, 0, 1)).norm(), 1e-15);
  EXPECT_LT((*eq.unproject(1440, 480) - Vec3(1, 0, 0)).norm(), 1e-15);  // longitude +90 deg
  EXPECT_LT((*eq.unproject(480, 480) - Vec3(-1, 0, 0)).norm(), 1e-15);
  EXPECT_LT((*eq.unproject(960, 0) - Vec3(0, -1, 0)).norm(), 1e-15);  // up is -y
  EXPECT_LT((*eq.unproject(0, 480) - Vec3(0, 0, -1)).norm(), 1e-15);  // behind the camera
  EXPECT_LT((eq.project(Vec3(0, 0, -2)) - Eigen::Vector2d(1920, 480)).norm(), 1e-9);
  EXPECT_FALSE(eq.project_px(Vec3::Zero()).has_value());

  // OPENCV_FISHEYE at 45 degrees along x: theta = pi / 4, theta_d = theta (1 + k1 theta^2).
  const CameraIntrinsics fe =
      camera(CameraModel::kOpenCvFisheye, {300, 310, 320, 240, 0.1, 0, 0, 0});
  const double theta = kPi / 4;
  EXPECT_NEAR(fe.project(Vec3(1, 0, 1)).x(), 300 * theta * (1 + 0.1 * theta * theta) + 320, 1e-9);
  EXPECT_NEAR(fe.project(Vec3(1, 0, 1)).y(), 240, 1e-12);
  // A ray 120 degrees from the axis (behind the image plane) is still imaged by a fisheye.
  const Vec3 behind(std::sin(2 * kPi / 3), 0, std::cos(2 * kPi / 3));
  const double theta_b = 2 * kPi / 3;
  EXPECT_NEAR(fe.project(behind).x(), 300 * theta_b * (1 + 0.1 * theta_b * theta_b) + 320, 1e-9);
  EXPECT_LT((*fe.unproject(fe.project(behind).x(), 240) - behind).norm(), 1e-9);

  // DIVISION: the ray of x_d = ((u - cx) / fx, (v - cy) / fy) is (x_d, 1 + k |x_d|^2).
  const CameraIntrinsics div = camera(CameraModel::kDivision, {500, 400, 320, 240, -0.2});
  const Vec3 expected = Vec3(0.4, -0.25, 1 - 0.2 * (0.16 + 0.0625)).normalized();
  EXPECT_LT((*div.unproject(320 + 200, 240 - 100) - expected).norm(), 1e-15);

  // FOV: r_d = atan(2 r tan(omega / 2)) / omega for the normalised radius r.
  const CameraIntrinsics fov = camera(CameraModel::kFov, {500, 500, 0, 0, 0.9});
  const double r = 0.5;
  EXPECT_NEAR(fov.project(Vec3(r, 0, 1)).x(), 500 * std::atan(2 * r * std::tan(0.45)) / 0.9, 1e-9);

  // FULL_OPENCV with only k1 is OPENCV with the same k1.
  const CameraIntrinsics full =
      camera(CameraModel::kFullOpenCv, {500, 480, 320, 240, 0.1, 0, 0, 0, 0, 0, 0, 0});
  const CameraIntrinsics cv = camera(CameraModel::kOpenCv, {500, 480, 320, 240, 0.1, 0, 0, 0});
  EXPECT_LT((full.project(Vec3(0.3, -0.2, 1)) - cv.project(Vec3(0.3, -0.2, 1))).norm(), 1e-9);

  // EUCM with alpha = 0 is a pinhole camera.
  const CameraIntrinsics eucm = camera(CameraModel::kEucm, {500, 480, 320, 240, 0, 1});
  EXPECT_LT((eucm.project(Vec3(0.3, -0.2, 1)) - Eigen::Vector2d(470, 144)).norm(), 1e-9);
}

TEST(CameraModelTable, InvalidParametersNameTheProblem) {
  std::string why;
  EXPECT_FALSE(camera(CameraModel::kOpenCvFisheye, {300, 300, 320, 240}).is_valid(&why));
  EXPECT_NE(why.find("OPENCV_FISHEYE has 4 parameters, expected 8"), std::string::npos) << why;
  EXPECT_NE(why.find("fx, fy, cx, cy, k1, k2, k3, k4"), std::string::npos) << why;
  EXPECT_FALSE(camera(CameraModel::kEquirectangular, {0, 960}).is_valid(&why));
  EXPECT_NE(why.find("EQUIRECTANGULAR"), std::string::npos) << why;
  EXPECT_FALSE(camera(CameraModel::kEucm, {400, 400, 320, 240, 1.5, 1}).is_valid(&why));
  EXPECT_NE(why.find("alpha"), std::string::npos) << why;
  EXPECT_FALSE(camera(CameraModel::kFisheye, {-300, 300, 320, 240}).is_valid(&why));
  EXPECT_FALSE(camera(CameraModel::kFov, {300, 300, 320, 240, NAN}).is_valid(&why));
}

// ---- triangulation from bearing vectors

/// A world point seen by 2-5 cameras of `k`, in every direction around them (behind them too
/// for the equirectangular camera), 1-4 m away.
struct BearingScene {
  Vec3 p_world;
  std::vector<Isometry3> poses;  // T_world_camera
};

BearingScene random_bearing_scene(std::mt19937& rng, const Case& c) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> distance(1.0, 4.0);
  std::uniform_int_distribution<int> count(2, 5);
  BearingScene scene;
  scene.p_world = 2.0 * Vec3(unit(rng), unit(rng), unit(rng));
  const int n = count(rng);
  const Vec3 mean_direction = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  for (int i = 0; i < n; ++i) {
    const Vec3 d = (mean_direction + 0.7 * Vec3(unit(rng), unit(rng), unit(rng))).normalized();
    const Vec3 centre = scene.p_world + distance(rng) * d;
    // The camera sees the point at a random ray of its field of view (at most 0.9 of it).
    const Vec3 ray = random_direction(rng, 0.9 * c.max_angle_deg);
    // R_world_camera maps the ray to the point's direction, rolled by a random angle about it.
    const Mat3 R_world_camera =
        Eigen::Quaterniond::FromTwoVectors(ray, (scene.p_world - centre).normalized())
            .toRotationMatrix() *
        Eigen::AngleAxisd(kPi * unit(rng), ray).toRotationMatrix();
    Isometry3 T = Isometry3::Identity();
    T.linear() = R_world_camera;
    T.translation() = centre;
    scene.poses.push_back(T);
  }
  return scene;
}

double max_pairwise_angle_deg(const BearingScene& s) {
  double best = 0.0;
  for (std::size_t i = 0; i < s.poses.size(); ++i) {
    for (std::size_t j = i + 1; j < s.poses.size(); ++j) {
      const Vec3 a = s.p_world - s.poses[i].translation();
      const Vec3 b = s.p_world - s.poses[j].translation();
      best = std::max(best, std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / kPi);
    }
  }
  return best;
}

TEST(BearingTriangulation, NoiselessPixelsOfEveryModelGiveTheExactPoint) {
  std::mt19937 rng(2601);
  for (const Case& c : every_model()) {
    SCOPED_TRACE(camera_model_name(c.k.model));
    int tried = 0;
    for (int trial = 0; trial < 60; ++trial) {
      const BearingScene scene = random_bearing_scene(rng, c);
      if (max_pairwise_angle_deg(scene) < 10.0) continue;
      std::vector<PixelView> views;
      for (const Isometry3& T : scene.poses) {
        const Eigen::Vector2d px = c.k.project(T.inverse() * scene.p_world);
        ASSERT_TRUE(px.allFinite());
        const std::optional<PixelView> view = make_pixel_view(T, c.k, px.x(), px.y());
        ASSERT_TRUE(view.has_value()) << px.transpose();
        views.push_back(*view);
      }
      const std::optional<TriangulatedPoint> point = triangulate(views);
      ASSERT_TRUE(point.has_value()) << "trial " << trial;
      EXPECT_LT((point->p_world - scene.p_world).norm(), 1e-7) << "trial " << trial;
      EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat3>(point->cov_world_m2).eigenvalues()(0), 0.0);
      ++tried;
    }
    EXPECT_GT(tried, 20);
  }
}

// NEES of the triangulated point against its covariance, with 1 px of noise on the RAW pixels
// of fisheye and equirectangular cameras: the bearing views carry each model's local resolution,
// so the mean NEES is near 3 (chi^2 with 3 degrees of freedom).
TEST(BearingTriangulation, CovarianceIsConsistentWithRawPixelNoise) {
  std::mt19937 rng(2602);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (const Case& c : every_model()) {
    const CameraProjection projection = camera_model_info(c.k.model).projection;
    if (projection == CameraProjection::kPerspective) continue;
    SCOPED_TRACE(camera_model_name(c.k.model));
    double nees_sum = 0.0;
    int n = 0;
    while (n < 400) {
      const BearingScene scene = random_bearing_scene(rng, c);
      if (max_pairwise_angle_deg(scene) < 10.0) continue;
      std::vector<PixelView> views;
      for (const Isometry3& T : scene.poses) {
        const Eigen::Vector2d px = c.k.project(T.inverse() * scene.p_world);
        const std::optional<PixelView> view =
            make_pixel_view(T, c.k, px.x() + noise(rng), px.y() + noise(rng));
        if (view) views.push_back(*view);
      }
      const std::optional<TriangulatedPoint> point = triangulate(views);
      if (!point) continue;
      const Vec3 e = point->p_world - scene.p_world;
      nees_sum += e.dot(point->cov_world_m2.ldlt().solve(e));
      ++n;
    }
    const double mean = nees_sum / n;
    EXPECT_GT(mean, 2.5);
    EXPECT_LT(mean, 3.6);
  }
}

}  // namespace
}  // namespace lmalign
