// Triangulation from pixel observations (method.md §6, `split --retriangulate`).
//
// 1. Linear DLT on normalised image coordinates: for each view with world-to-camera [R | t] and
//    normalised pixel (x, y), the rows x * P3 - P1 and y * P3 - P2 of a 2N x 4 homogeneous system.
//    The world coordinates are first centred on the camera centres and scaled to unit mean
//    distance (Hartley's conditioning); the null vector comes from a JacobiSVD.
// 2. Gauss-Newton on the pixel reprojection error (pinhole, raw pixels, no distortion) in world
//    coordinates, with step halving if a step increases the cost or puts the point behind a camera.
// 3. Covariance (J^T J)^-1 sigma^2 from the Jacobian at the final point.
#include "lmalign/map/triangulation.hpp"
#include "lmalign/core/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

namespace lmalign {

namespace {

/// Normal matrices with lambda_min / lambda_max below this are treated as singular.
constexpr double kMinReciprocalCondition = 1e-12;
/// Gauss-Newton stops when the step is below this fraction of (1 + |p|), metres.
constexpr double kRelativeStepTolerance = 1e-12;

struct WorldToCamera {
  Mat3 R;  // rotation world -> camera
  Vec3 t;  // p_camera = R p_world + t
  Vec3 centre_world;
};

struct Linearisation {
  double cost = 0.0;  // sum of squared pixel residuals, px^2
  Mat3 H = Mat3::Zero();
  Vec3 g = Vec3::Zero();
  bool in_front = true;
};

// Residuals and normal equations at p_world; in_front is false if any camera sees z <= 0.
Linearisation linearise(const std::vector<WorldToCamera>& cameras,
                        const std::vector<PixelView>& views, const PinholeIntrinsics& k_all,
                        const Vec3& p_world) {
  Linearisation lin;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const PinholeIntrinsics& k = views[i].intrinsics ? *views[i].intrinsics : k_all;
    const Vec3 pc = cameras[i].R * p_world + cameras[i].t;
    if (!(pc.z() > 0.0)) {
      lin.in_front = false;
      return lin;
    }
    const double inv_z = 1.0 / pc.z();
    const Eigen::Vector2d r(k.fx_px * pc.x() * inv_z + k.cx_px - views[i].u_px,
                            k.fy_px * pc.y() * inv_z + k.cy_px - views[i].v_px);
    Eigen::Matrix<double, 2, 3> d_proj;
    d_proj << k.fx_px * inv_z, 0.0, -k.fx_px * pc.x() * inv_z * inv_z,  //
        0.0, k.fy_px * inv_z, -k.fy_px * pc.y() * inv_z * inv_z;
    const Eigen::Matrix<double, 2, 3> J = d_proj * cameras[i].R;
    lin.cost += r.squaredNorm();
    lin.H += J.transpose() * J;
    lin.g += J.transpose() * r;
  }
  return lin;
}

// Whether a decomposition of H succeeded and H is positive definite and well conditioned.
bool well_conditioned(const Eigen::SelfAdjointEigenSolver<Mat3>& eig) {
  if (eig.info() != Eigen::Success) return false;
  const double lmin = eig.eigenvalues()(0);
  const double lmax = eig.eigenvalues()(2);
  return lmax > 0.0 && lmin > kMinReciprocalCondition * lmax;
}
bool well_conditioned(const Mat3& H) {
  return H.allFinite() &&
         well_conditioned(Eigen::SelfAdjointEigenSolver<Mat3>(H, Eigen::EigenvaluesOnly));
}

std::optional<Vec3> dlt(const std::vector<WorldToCamera>& cameras,
                        const std::vector<PixelView>& views, const PinholeIntrinsics& k) {
  const std::size_t n = cameras.size();
  // Conditioning: p_world = centroid + scale * p_normalised.
  Vec3 centroid = Vec3::Zero();
  for (const auto& c : cameras) centroid += c.centre_world;
  centroid /= static_cast<double>(n);
  double mean_distance = 0.0;
  for (const auto& c : cameras) mean_distance += (c.centre_world - centroid).norm();
  mean_distance /= static_cast<double>(n);
  const double scale = mean_distance > 0.0 ? mean_distance : 1.0;

  Eigen::MatrixXd A(2 * n, 4);
  for (std::size_t i = 0; i < n; ++i) {
    // Projection of the normalised world point: R (centroid + scale * x) + t.
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = cameras[i].R * scale;
    P.col(3) = cameras[i].R * centroid + cameras[i].t;
    const PinholeIntrinsics& k_view = views[i].intrinsics ? *views[i].intrinsics : k;
    const Vec3 ray = k_view.unproject(views[i].u_px, views[i].v_px);
    A.row(2 * i) = ray.x() * P.row(2) - P.row(0);
    A.row(2 * i + 1) = ray.y() * P.row(2) - P.row(1);
  }
  if (!A.allFinite()) return std::nullopt;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  // A point at (or near) infinity has no Euclidean position.
  if (!(std::abs(X(3)) > 1e-12 * X.head<3>().norm())) return std::nullopt;
  const Vec3 p_world = centroid + scale * X.head<3>() / X(3);
  if (!p_world.allFinite()) return std::nullopt;
  return p_world;
}

double max_parallax_deg(const std::vector<WorldToCamera>& cameras, const Vec3& p_world) {
  double best = 0.0;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Vec3 a = p_world - cameras[i].centre_world;
    for (std::size_t j = i + 1; j < cameras.size(); ++j) {
      const Vec3 b = p_world - cameras[j].centre_world;
      // atan2 of |a x b| and a . b is accurate at small and large angles alike.
      const double angle = std::atan2(a.cross(b).norm(), a.dot(b));
      best = std::max(best, angle);
    }
  }
  return best * 180.0 / kPi;
}

}  // namespace

std::optional<PixelView> make_pixel_view(const Isometry3& T_world_camera,
                                         const std::optional<CameraIntrinsics>& camera, double u_px,
                                         double v_px) {
  PixelView view{T_world_camera, u_px, v_px, std::nullopt};
  if (!camera) return view;
  if (!camera->is_valid()) return std::nullopt;
  if (static_cast<int>(camera->model) <= static_cast<int>(CameraModel::kOpenCv)) {
    // The camera's own image plane: its undistorted pixel and pinhole part.
    const std::optional<Eigen::Vector2d> undistorted = camera->undistort_px(u_px, v_px);
    if (!undistorted) return std::nullopt;
    view.u_px = undistorted->x();
    view.v_px = undistorted->y();
    view.intrinsics = camera->pinhole();
    return view;
  }
  return make_bearing_view(T_world_camera, *camera, u_px, v_px);
}

std::optional<PixelView> make_bearing_view(const Isometry3& T_world_camera,
                                           const CameraIntrinsics& camera, double u_px,
                                           double v_px) {
  if (!camera.is_valid()) return std::nullopt;
  const std::optional<Vec3> bearing = camera.unproject(u_px, v_px);
  if (!bearing) return std::nullopt;
  const Vec3& b = *bearing;
  // A tangent basis e1, e2 with e1 x e2 = b.
  const Vec3 helper = std::abs(b.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 e1 = helper.cross(b).normalized();
  const Vec3 e2 = b.cross(e1);
  // A = d(tangent)/d(pixel) by central differences of the unprojection: the tangent coordinates
  // of a nearby pixel's ray are its gnomonic projection onto the plane at b.
  constexpr double kStepPx = 1e-3;
  Eigen::Matrix2d A;
  for (int c = 0; c < 2; ++c) {
    const double du = c == 0 ? kStepPx : 0.0;
    const double dv = c == 1 ? kStepPx : 0.0;
    const std::optional<Vec3> plus = camera.unproject(u_px + du, v_px + dv);
    const std::optional<Vec3> minus = camera.unproject(u_px - du, v_px - dv);
    if (!plus || !minus || !(plus->dot(b) > 0.0) || !(minus->dot(b) > 0.0)) return std::nullopt;
    const Eigen::Vector2d tp(plus->dot(e1) / plus->dot(b), plus->dot(e2) / plus->dot(b));
    const Eigen::Vector2d tm(minus->dot(e1) / minus->dot(b), minus->dot(e2) / minus->dot(b));
    A.col(c) = (tp - tm) / (2.0 * kStepPx);
  }
  // Pixel noise sigma I maps to the tangent covariance sigma^2 A A^T = sigma^2 U S^2 U^T: along
  // the columns of U the tangent error has standard deviation sigma s_i, so a pinhole camera
  // with those axes and focal lengths 1 / s_i turns it back into isotropic pixel noise.
  const Eigen::JacobiSVD<Eigen::Matrix2d> svd(A, Eigen::ComputeFullU);
  Eigen::Matrix2d U = svd.matrixU();
  if (U.determinant() < 0.0) U.col(1) = -U.col(1);
  const Eigen::Vector2d s = svd.singularValues();
  if (!A.allFinite() || !(s(1) > 0.0) || !(s(0) < std::numeric_limits<double>::infinity())) {
    return std::nullopt;
  }
  Mat3 R_camera_virtual;
  R_camera_virtual.col(0) = U(0, 0) * e1 + U(1, 0) * e2;
  R_camera_virtual.col(1) = U(0, 1) * e1 + U(1, 1) * e2;
  R_camera_virtual.col(2) = b;
  Isometry3 T_camera_virtual = Isometry3::Identity();
  T_camera_virtual.linear() = R_camera_virtual;
  PixelView view{T_world_camera * T_camera_virtual, 0.0, 0.0,
                 PinholeIntrinsics{1.0 / s(0), 1.0 / s(1), 0.0, 0.0}};
  if (!view.intrinsics->is_valid() || !view.T_world_camera.matrix().allFinite()) {
    return std::nullopt;
  }
  return view;
}

std::optional<TriangulatedPoint> triangulate(const std::vector<PixelView>& views,
                                             const TriangulationOptions& options) {
  if (views.size() < 2) return std::nullopt;
  const PinholeIntrinsics& k = options.intrinsics;
  if (!k.is_valid() || !(options.pixel_sigma_px > 0.0) || !std::isfinite(options.pixel_sigma_px)) {
    return std::nullopt;
  }

  std::vector<WorldToCamera> cameras;
  cameras.reserve(views.size());
  for (const PixelView& view : views) {
    if (!view.T_world_camera.matrix().allFinite() || !std::isfinite(view.u_px) ||
        !std::isfinite(view.v_px) || (view.intrinsics && !view.intrinsics->is_valid())) {
      return std::nullopt;
    }
    const Isometry3 T_camera_world = view.T_world_camera.inverse();
    cameras.push_back(
        {T_camera_world.linear(), T_camera_world.translation(), view.T_world_camera.translation()});
  }

  const std::optional<Vec3> initial = dlt(cameras, views, k);
  if (!initial) return std::nullopt;
  Vec3 p = *initial;
  Linearisation lin = linearise(cameras, views, k, p);
  if (!lin.in_front) return std::nullopt;

  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    if (!well_conditioned(lin.H)) return std::nullopt;
    const Vec3 step = -lin.H.ldlt().solve(lin.g);
    if (!step.allFinite()) return std::nullopt;
    // Accept the full Gauss-Newton step if it does not increase the cost; else halve it.
    double alpha = 1.0;
    bool accepted = false;
    for (int halving = 0; halving < 30; ++halving, alpha *= 0.5) {
      const Vec3 candidate = p + alpha * step;
      Linearisation next = linearise(cameras, views, k, candidate);
      if (next.in_front && next.cost <= lin.cost) {
        p = candidate;
        lin = next;
        accepted = true;
        break;
      }
    }
    if (!accepted) break;  // no descent along the step: at the minimum to machine precision
    if (alpha * step.norm() <= kRelativeStepTolerance * (1.0 + p.norm())) break;
  }

  if (!lin.in_front || !lin.H.allFinite()) return std::nullopt;
  // One decomposition for the conditioning test and for (J^T J)^-1 = V diag(1 / lambda) V^T:
  // positive definite by construction. The 3x3 cofactor inverse (Mat3::inverse()) is not: at a
  // condition number near the accepted 1e12 (a point a few centimetres from the cameras, found by
  // fuzz_map_reader) it returned a matrix with a negative diagonal.
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(lin.H);
  if (!well_conditioned(eig)) return std::nullopt;
  TriangulatedPoint result;
  result.p_world = p;
  const Mat3& V = eig.eigenvectors();
  result.cov_world_m2 = V * eig.eigenvalues().cwiseInverse().asDiagonal() * V.transpose() *
                        (options.pixel_sigma_px * options.pixel_sigma_px);
  result.cov_world_m2 = 0.5 * (result.cov_world_m2 + result.cov_world_m2.transpose()).eval();
  result.max_parallax_deg = max_parallax_deg(cameras, p);
  result.rms_reprojection_px = std::sqrt(lin.cost / static_cast<double>(views.size()));
  if (!result.p_world.allFinite() || !result.cov_world_m2.allFinite() ||
      !std::isfinite(result.max_parallax_deg) || !std::isfinite(result.rms_reprojection_px)) {
    return std::nullopt;
  }
  return result;
}

}  // namespace lmalign
