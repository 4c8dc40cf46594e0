#include <cmath>

#include <gtest/gtest.h>

#include "lmalign/core/geometry.hpp"

namespace lmalign {
namespace {

TEST(PoseFromXyzRpy, RotationOrderIsZYX) {
  // Rz(yaw) Ry(pitch) Rx(roll): roll applied first. Check on basis vectors with 90 degree angles.
  const Isometry3 T = pose_from_xyz_rpy_deg(1, 2, 3, 90, 0, 90);
  // Rx(90) maps y -> z, then Rz(90) leaves z: so y -> z.
  EXPECT_TRUE((T.linear() * Vec3::UnitY()).isApprox(Vec3::UnitZ(), 1e-12));
  // x: Rx leaves x, Rz(90) maps x -> y.
  EXPECT_TRUE((T.linear() * Vec3::UnitX()).isApprox(Vec3::UnitY(), 1e-12));
  EXPECT_TRUE(T.translation().isApprox(Vec3(1, 2, 3)));
  const Isometry3 P = pose_from_xyz_rpy_deg(0, 0, 0, 0, 90, 0);  // Ry(90): z -> x
  EXPECT_TRUE((P.linear() * Vec3::UnitZ()).isApprox(Vec3::UnitX(), 1e-12));
}

TEST(XyzRpyFromPose, InvertsPoseFromXyzRpy) {
  const Isometry3 T = pose_from_xyz_rpy_deg(0.5, -1, 2, 10, -20, 135);
  const auto v = xyz_rpy_deg_from_pose(T);
  EXPECT_NEAR(v[0], 0.5, 1e-12);
  EXPECT_NEAR(v[1], -1, 1e-12);
  EXPECT_NEAR(v[2], 2, 1e-12);
  EXPECT_NEAR(v[3], 10, 1e-9);
  EXPECT_NEAR(v[4], -20, 1e-9);
  EXPECT_NEAR(v[5], 135, 1e-9);
}

TEST(TransformError, AngleAndTranslation) {
  const Isometry3 a = pose_from_xyz_rpy_deg(1, 0, 0, 0, 0, 10);
  const Isometry3 b = pose_from_xyz_rpy_deg(1, 0.03, -0.04, 0, 0, 13);
  const TransformError e = transform_error(b, a);
  EXPECT_NEAR(e.rotation_deg, 3.0, 1e-9);
  EXPECT_NEAR(e.translation_m, 0.05, 1e-12);
  EXPECT_EQ(transform_error(a, a).rotation_deg, 0.0);
  EXPECT_NEAR(rotation_angle_deg(pose_from_xyz_rpy_deg(0, 0, 0, 180, 0, 0).linear()), 180.0, 1e-9);
}

TEST(TransformCovariances, RotatesByTheLinearPartOnly) {
  const Isometry3 T = pose_from_xyz_rpy_deg(3.0, -2.0, 1.0, 10.0, -20.0, 30.0);
  Mat3 A;
  A << 4, 1, 0, 1, 3, -1, 0, -1, 2;  // symmetric positive definite
  const std::vector<Mat3> moved = transform_covariances(T, {A, Mat3::Identity()});
  ASSERT_EQ(moved.size(), 2u);
  const Mat3 R = T.linear();
  EXPECT_TRUE(moved[0].isApprox(R * A * R.transpose(), 1e-15));
  EXPECT_TRUE(moved[1].isApprox(Mat3::Identity(), 1e-15));  // isotropic stays isotropic
  // The variance along a moved direction R u is that along u before the move.
  const Vec3 u = Vec3(1, 2, -1).normalized();
  EXPECT_NEAR((R * u).dot(moved[0] * (R * u)), u.dot(A * u), 1e-12);
  // Moving back restores them.
  EXPECT_TRUE(transform_covariances(T.inverse(), moved)[0].isApprox(A, 1e-14));
  EXPECT_TRUE(transform_covariances(T, {}).empty());
}

}  // namespace
}  // namespace lmalign
