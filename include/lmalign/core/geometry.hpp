// Rigid-transform helpers: building poses from the paper's (x, y, z, roll, pitch, yaw), applying
// transforms to point lists, and errors of an estimate against a known true transform.
#pragma once

#include <vector>

#include "lmalign/core/types.hpp"

namespace lmalign {

/// pi, and degrees to radians (multiply by it).
inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kRadPerDeg = kPi / 180.0;

/// The paper's displacement (method.md §5): p' = R p + t with R = Rz(yaw) Ry(pitch) Rx(roll)
/// (MRPT CPose3D(x, y, z, yaw, pitch, roll)); translations in metres, angles in degrees.
/// It acts about the world origin, not about a map centroid.
Isometry3 pose_from_xyz_rpy_deg(double x_m, double y_m, double z_m, double roll_deg,
                                double pitch_deg, double yaw_deg);

/// Inverse of pose_from_xyz_rpy_deg: (x, y, z) in metres and (roll, pitch, yaw) in degrees with
/// R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-90, 90].
Eigen::Matrix<double, 6, 1> xyz_rpy_deg_from_pose(const Isometry3& T);

/// Rotation angle of R in degrees, in [0, 180]: acos((trace(R) - 1) / 2) (method.md §4), computed
/// as atan2(|vee(R - R^T)| / 2, (trace(R) - 1) / 2) so that small angles keep full precision.
double rotation_angle_deg(const Mat3& R);

/// Error of an estimated transform against the true one (method.md §4).
struct TransformError {
  /// Angle of R_true^T R_est, degrees.
  double rotation_deg = 0.0;
  /// |t_est - t_true|, metres (the translation of T_true^-1 * T_est has this norm too).
  double translation_m = 0.0;
};

/// Error of T_est against T_true, both T_target_source.
TransformError transform_error(const Isometry3& T_est, const Isometry3& T_true);

/// Returns T * p for every point (output[i] = T * points[i]).
Points3 transform_points(const Isometry3& T, const Points3& points);

/// Writes T * p into `out` (resized to points.size()). `out` must not alias `points`.
void transform_points(const Isometry3& T, const Points3& points, Points3& out);

/// Returns R C R^T for every covariance (3x3, m^2), R = T.linear(): the covariances of points
/// moved by T, expressed in T's output frame (a translation does not change a covariance). Used
/// to move source landmark covariances with their displaced points.
std::vector<Mat3> transform_covariances(const Isometry3& T,
                                        const std::vector<Mat3>& covariances_m2);

/// True if every entry of the 4x4 matrix is finite.
bool is_finite(const Isometry3& T);

/// True when T's linear part is a rotation (orthonormal to 1e-6, determinant +1), its last row
/// (0, 0, 0, 1) and T finite.
bool is_rigid_transform(const Isometry3& T);

/// [v]x, the 3x3 cross-product (skew-symmetric) matrix: skew(v) * w == v.cross(w).
inline Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

/// The 6x6 adjoint of T in registration/uncertainty.hpp's (rho m, phi rad) ordering,
/// Ad(T) = [[R, [t]x R], [0, R]]: a left perturbation xi_b in frame b becomes Ad(T_ab) xi_b in
/// frame a (T_ab Exp(xi_b) = Exp(Ad(T_ab) xi_b) T_ab); covariances move as Ad C Ad^T.
Mat6 se3_adjoint(const Isometry3& T);

}  // namespace lmalign
