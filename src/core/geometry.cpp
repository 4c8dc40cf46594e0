#include "lmalign/core/geometry.hpp"

#include <algorithm>
#include <cmath>

namespace lmalign {

namespace {
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRadToDeg = 180.0 / M_PI;
}  // namespace

Isometry3 pose_from_xyz_rpy_deg(double x_m, double y_m, double z_m, double roll_deg,
                                double pitch_deg, double yaw_deg) {
  const Mat3 R = (Eigen::AngleAxisd(yaw_deg * kDegToRad, Vec3::UnitZ()) *
                  Eigen::AngleAxisd(pitch_deg * kDegToRad, Vec3::UnitY()) *
                  Eigen::AngleAxisd(roll_deg * kDegToRad, Vec3::UnitX()))
                     .toRotationMatrix();
  Isometry3 T = Isometry3::Identity();
  T.linear() = R;
  T.translation() = Vec3(x_m, y_m, z_m);
  return T;
}

Eigen::Matrix<double, 6, 1> xyz_rpy_deg_from_pose(const Isometry3& T) {
  const Mat3 R = T.linear();
  Eigen::Matrix<double, 6, 1> v;
  v.head<3>() = T.translation();
  v[3] = std::atan2(R(2, 1), R(2, 2)) * kRadToDeg;                // roll
  v[4] = std::asin(std::clamp(-R(2, 0), -1.0, 1.0)) * kRadToDeg;  // pitch
  v[5] = std::atan2(R(1, 0), R(0, 0)) * kRadToDeg;                // yaw
  return v;
}

double rotation_angle_deg(const Mat3& R) {
  // acos((trace - 1) / 2) loses half the digits near 0 (acos(1 - 1e-16) = 1.4e-8 rad), so use
  // atan2(sin, cos) with sin from the skew-symmetric part: accurate at every angle.
  const double c = 0.5 * (R.trace() - 1.0);
  const Vec3 axis_sin(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  const double s = 0.5 * axis_sin.norm();
  return std::atan2(s, std::clamp(c, -1.0, 1.0)) * kRadToDeg;
}

TransformError transform_error(const Isometry3& T_est, const Isometry3& T_true) {
  TransformError e;
  e.rotation_deg = rotation_angle_deg(T_true.linear().transpose() * T_est.linear());
  e.translation_m = (T_est.translation() - T_true.translation()).norm();
  return e;
}

Points3 transform_points(const Isometry3& T, const Points3& points) {
  Points3 out;
  transform_points(T, points, out);
  return out;
}

void transform_points(const Isometry3& T, const Points3& points, Points3& out) {
  out.resize(points.size());
  const Mat3 R = T.linear();
  const Vec3 t = T.translation();
  for (std::size_t i = 0; i < points.size(); ++i) out[i] = R * points[i] + t;
}

std::vector<Mat3> transform_covariances(const Isometry3& T,
                                        const std::vector<Mat3>& covariances_m2) {
  const Mat3 R = T.linear();
  std::vector<Mat3> out;
  out.reserve(covariances_m2.size());
  for (const Mat3& C : covariances_m2) out.push_back(R * C * R.transpose());
  return out;
}

bool is_finite(const Isometry3& T) { return T.matrix().allFinite(); }

Mat6 se3_adjoint(const Isometry3& T) {
  Mat6 A = Mat6::Zero();
  const Mat3 R = T.linear();
  A.block<3, 3>(0, 0) = R;
  A.block<3, 3>(0, 3) = skew(T.translation()) * R;
  A.block<3, 3>(3, 3) = R;
  return A;
}

bool is_rigid_transform(const Isometry3& T) {
  if (!T.matrix().allFinite()) return false;
  const Mat3 R = T.linear();
  if (!((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-6)) return false;
  if (!(std::abs(R.determinant() - 1.0) < 1e-6)) return false;
  const Eigen::RowVector4d last = T.matrix().row(3);
  return last.isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-12);
}

}  // namespace lmalign
