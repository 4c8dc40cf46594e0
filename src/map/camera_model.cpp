// The camera model table (include/lmalign/map/camera_model.hpp): the equations of COLMAP's
// models (colmap/src/colmap/sensor/models.h), written here from their definitions.
#include "lmalign/map/camera_model.hpp"

#include <array>
#include <cmath>
#include <limits>

#include <Eigen/LU>

#include "lmalign/core/geometry.hpp"

namespace lmalign {

namespace {

using Vec2 = Eigen::Vector2d;

/// Additive distortion of a model's plane coordinates (normalised x/z, y/z for perspective
/// models; theta-scaled for fisheye models): the offset (dx, dy), with `e` the model's extra
/// parameters (those after the focal lengths and principal point).
using Distortion = Vec2 (*)(const double* e, double x, double y);

Vec2 no_distortion(const double*, double, double) { return {0.0, 0.0}; }

Vec2 simple_radial(const double* e, double x, double y) {
  const double r2 = x * x + y * y;
  const double radial = e[0] * r2;
  return {x * radial, y * radial};
}

Vec2 radial(const double* e, double x, double y) {
  const double r2 = x * x + y * y;
  const double radial = e[0] * r2 + e[1] * r2 * r2;
  return {x * radial, y * radial};
}

// k1, k2, p1, p2.
Vec2 opencv(const double* e, double x, double y) {
  const double x2 = x * x;
  const double y2 = y * y;
  const double r2 = x2 + y2;
  const double radial = e[0] * r2 + e[1] * r2 * r2;
  const double xy = x * y;
  return {x * radial + 2.0 * e[2] * xy + e[3] * (r2 + 2.0 * x2),
          y * radial + 2.0 * e[3] * xy + e[2] * (r2 + 2.0 * y2)};
}

// k1, k2, p1, p2, k3, k4, k5, k6: OpenCV's rational model.
Vec2 full_opencv(const double* e, double x, double y) {
  const double x2 = x * x;
  const double y2 = y * y;
  const double r2 = x2 + y2;
  const double r4 = r2 * r2;
  const double r6 = r4 * r2;
  const double radial =
      (1.0 + e[0] * r2 + e[1] * r4 + e[4] * r6) / (1.0 + e[5] * r2 + e[6] * r4 + e[7] * r6);
  const double xy = x * y;
  return {x * radial + 2.0 * e[2] * xy + e[3] * (r2 + 2.0 * x2) - x,
          y * radial + 2.0 * e[3] * xy + e[2] * (r2 + 2.0 * y2) - y};
}

// k1, k2, k3, k4 on theta.
Vec2 opencv_fisheye(const double* e, double x, double y) {
  const double t2 = x * x + y * y;
  const double t4 = t2 * t2;
  const double radial = e[0] * t2 + e[1] * t4 + e[2] * t4 * t2 + e[3] * t4 * t4;
  return {x * radial, y * radial};
}

// k1, k2, p1, p2, k3, k4, sx1, sy1.
Vec2 thin_prism(const double* e, double x, double y) {
  const double x2 = x * x;
  const double y2 = y * y;
  const double r2 = x2 + y2;
  const double r4 = r2 * r2;
  const double radial = e[0] * r2 + e[1] * r4 + e[4] * r4 * r2 + e[5] * r4 * r4;
  const double xy = x * y;
  return {x * radial + 2.0 * e[2] * xy + e[3] * (r2 + 2.0 * x2) + e[6] * r2,
          y * radial + 2.0 * e[3] * xy + e[2] * (r2 + 2.0 * y2) + e[7] * r2};
}

// k0..k5, p0, p1, s0..s3 (Meta's Fisheye624): radial on theta, then tangential and thin prism.
Vec2 rad_tan_thin_prism(const double* e, double x, double y) {
  const double t2 = x * x + y * y;
  double scale = 1.0;
  double power = 1.0;
  for (int i = 0; i < 6; ++i) {
    power *= t2;
    scale += e[i] * power;
  }
  const double a = scale * x;
  const double b = scale * y;
  const double a2 = a * a;
  const double b2 = b * b;
  const double ab = a * b;
  const double r2 = a2 + b2;
  const double r4 = r2 * r2;
  const double p0 = e[6];
  const double p1 = e[7];
  const double da = 2.0 * p1 * ab + p0 * (r2 + 2.0 * a2) + e[8] * r2 + e[9] * r4;
  const double db = 2.0 * p0 * ab + p1 * (r2 + 2.0 * b2) + e[10] * r2 + e[11] * r4;
  return {a + da - x, b + db - y};
}

/// One row: the public info, where the focal lengths are (1: f; 2: fx, fy; 0: none), and the
/// model's maps.
struct ModelRow;
using Unproject = std::optional<Vec3> (*)(const ModelRow&, const double* p, double u, double v);
using Project = std::optional<Vec2> (*)(const ModelRow&, const double* p, const Vec3& X);

struct ModelRow {
  CameraModelInfo info;
  int num_focal;
  Distortion distortion;
  Unproject unproject;
  Project project;
};

/// Focal lengths and principal point of a row with num_focal 1 or 2.
struct Intrinsic {
  double fx, fy, cx, cy;
  const double* extra;
};
Intrinsic intrinsic(const ModelRow& row, const double* p) {
  if (row.num_focal == 1) return {p[0], p[0], p[1], p[2], p + 3};
  return {p[0], p[1], p[2], p[3], p + 4};
}

/// Solves x + d(x) = x0 for x: COLMAP's fixed-point iteration x <- x0 - d(x) (at most 100
/// steps, to 1e-12), and where that does not converge, Newton's method with a numerical
/// Jacobian and a trust region (steps of at most 0.1 (1 + |x|)), as COLMAP's
/// IterativeUndistortion. nullopt if neither converges or a value is not finite.
std::optional<Vec2> invert_distortion(Distortion d, const double* e, const Vec2& x0) {
  if (d == &no_distortion) return x0;
  double x = x0.x();
  double y = x0.y();
  for (int i = 0; i < 100; ++i) {
    const Vec2 dx = d(e, x, y);
    const double nx = x0.x() - dx.x();
    const double ny = x0.y() - dx.y();
    if (!std::isfinite(nx) || !std::isfinite(ny)) break;
    const bool converged =
        std::abs(nx - x) + std::abs(ny - y) <= 1e-12 * (1.0 + std::abs(nx) + std::abs(ny));
    x = nx;
    y = ny;
    if (converged) return Vec2(x, y);
  }
  Vec2 z = x0;
  for (int i = 0; i < 100; ++i) {
    const Vec2 g = z + d(e, z.x(), z.y()) - x0;
    if (!g.allFinite()) return std::nullopt;
    Eigen::Matrix2d J;
    for (int c = 0; c < 2; ++c) {
      const double h = 1e-7 * (1.0 + std::abs(z(c)));
      Vec2 zp = z;
      Vec2 zm = z;
      zp(c) += h;
      zm(c) -= h;
      J.col(c) = (zp + d(e, zp.x(), zp.y()) - zm - d(e, zm.x(), zm.y())) / (2.0 * h);
    }
    Vec2 step = J.partialPivLu().solve(g);
    if (!step.allFinite()) return std::nullopt;
    const double radius = 0.1 * (1.0 + z.norm());
    if (step.norm() > radius) step *= radius / step.norm();
    z -= step;
    if (step.norm() <= 1e-14 * (1.0 + z.norm())) break;
  }
  const Vec2 g = z + d(e, z.x(), z.y()) - x0;
  if (!z.allFinite() || !(g.norm() <= 1e-9 * (1.0 + x0.norm()))) return std::nullopt;
  return z;
}

// ---- perspective: normalised plane, additive distortion

std::optional<Vec3> unproject_perspective(const ModelRow& row, const double* p, double u,
                                          double v) {
  const Intrinsic k = intrinsic(row, p);
  const std::optional<Vec2> x =
      invert_distortion(row.distortion, k.extra, Vec2((u - k.cx) / k.fx, (v - k.cy) / k.fy));
  if (!x) return std::nullopt;
  return Vec3(x->x(), x->y(), 1.0).normalized();
}

std::optional<Vec2> project_perspective(const ModelRow& row, const double* p, const Vec3& X) {
  if (!(X.z() > 0.0)) return std::nullopt;
  const Intrinsic k = intrinsic(row, p);
  const double x = X.x() / X.z();
  const double y = X.y() / X.z();
  const Vec2 d = row.distortion(k.extra, x, y);
  return Vec2(k.fx * (x + d.x()) + k.cx, k.fy * (y + d.y()) + k.cy);
}

// ---- fisheye: theta-scaled plane, additive distortion

std::optional<Vec3> unproject_fisheye(const ModelRow& row, const double* p, double u, double v) {
  const Intrinsic k = intrinsic(row, p);
  const std::optional<Vec2> t =
      invert_distortion(row.distortion, k.extra, Vec2((u - k.cx) / k.fx, (v - k.cy) / k.fy));
  if (!t) return std::nullopt;
  const double theta = t->norm();
  if (!(theta <= kPi)) return std::nullopt;
  if (theta < 1e-12) return Vec3(t->x(), t->y(), 1.0).normalized();
  const double s = std::sin(theta) / theta;
  return Vec3(t->x() * s, t->y() * s, std::cos(theta));
}

std::optional<Vec2> project_fisheye(const ModelRow& row, const double* p, const Vec3& X) {
  const double r = std::hypot(X.x(), X.y());
  Vec2 t(0.0, 0.0);
  if (r > 0.0) {
    const double theta = std::atan2(r, X.z());
    t = Vec2(X.x(), X.y()) * (theta / r);
  } else if (!(X.z() > 0.0)) {
    return std::nullopt;  // on the backward axis (or zero): no azimuth
  }
  const Intrinsic k = intrinsic(row, p);
  const Vec2 d = row.distortion(k.extra, t.x(), t.y());
  return Vec2(k.fx * (t.x() + d.x()) + k.cx, k.fy * (t.y() + d.y()) + k.cy);
}

// ---- FOV (Devernay and Faugeras): r_d = atan(2 r tan(omega / 2)) / omega

/// r_u / r_d at the distorted radius r_d: tan(r_d omega) / (2 r_d tan(omega / 2)).
double fov_undistortion_factor(double omega, double r_d) {
  if (omega == 0.0) return 1.0;
  const double t = std::tan(0.5 * omega);
  if (r_d == 0.0) return omega / (2.0 * t);
  return std::tan(r_d * omega) / (2.0 * r_d * t);
}

std::optional<Vec3> unproject_fov(const ModelRow& row, const double* p, double u, double v) {
  const Intrinsic k = intrinsic(row, p);
  const Vec2 x((u - k.cx) / k.fx, (v - k.cy) / k.fy);
  const double omega = k.extra[0];
  if (!(std::abs(x.norm() * omega) < 0.5 * kPi)) return std::nullopt;  // at or beyond 90 deg
  const Vec2 xu = x * fov_undistortion_factor(omega, x.norm());
  return Vec3(xu.x(), xu.y(), 1.0).normalized();
}

std::optional<Vec2> project_fov(const ModelRow& row, const double* p, const Vec3& X) {
  if (!(X.z() > 0.0)) return std::nullopt;
  const Intrinsic k = intrinsic(row, p);
  const Vec2 x(X.x() / X.z(), X.y() / X.z());
  const double omega = k.extra[0];
  const double r = x.norm();
  double factor = 1.0;
  if (omega != 0.0) {
    const double t = std::tan(0.5 * omega);
    factor = r == 0.0 ? 2.0 * t / omega : std::atan(2.0 * r * t) / (r * omega);
  }
  return Vec2(k.fx * x.x() * factor + k.cx, k.fy * x.y() * factor + k.cy);
}

// ---- division (Fitzgibbon): the ray of the distorted point x_d is (x_d, 1 + k |x_d|^2)

std::optional<Vec3> unproject_division(const ModelRow& row, const double* p, double u, double v) {
  const Intrinsic k = intrinsic(row, p);
  const Vec2 x((u - k.cx) / k.fx, (v - k.cy) / k.fy);
  const Vec3 ray(x.x(), x.y(), 1.0 + k.extra[0] * x.squaredNorm());
  if (!(ray.norm() > 0.0)) return std::nullopt;
  return ray.normalized();
}

std::optional<Vec2> project_division(const ModelRow& row, const double* p, const Vec3& X) {
  // x_d = s (X, Y) with k rho^2 s^2 - Z s + 1 = 0, rho = |(X, Y)|: s = 2 / (Z + sqrt(Z^2 - 4 k
  // rho^2)), the root that tends to 1 / Z as k -> 0.
  const Intrinsic k = intrinsic(row, p);
  const double rho2 = X.x() * X.x() + X.y() * X.y();
  const double disc2 = X.z() * X.z() - 4.0 * k.extra[0] * rho2;
  if (!(disc2 >= 0.0)) return std::nullopt;
  const double denominator = X.z() + std::sqrt(disc2);
  if (!(denominator > 0.0)) return std::nullopt;
  const double s = 2.0 / denominator;
  return Vec2(k.fx * s * X.x() + k.cx, k.fy * s * X.y() + k.cy);
}

// ---- EUCM (Khomutenko et al.): x = X / (alpha rho + (1 - alpha) Z), rho^2 = beta (X^2 + Y^2)
// + Z^2

std::optional<Vec3> unproject_eucm(const ModelRow& row, const double* p, double u, double v) {
  const Intrinsic k = intrinsic(row, p);
  const double alpha = k.extra[0];
  const double beta = k.extra[1];
  const Vec2 m((u - k.cx) / k.fx, (v - k.cy) / k.fy);
  const double r2 = m.squaredNorm();
  const double radicand = 1.0 - (2.0 * alpha - 1.0) * beta * r2;
  if (!(radicand >= 0.0)) return std::nullopt;
  const double denominator = alpha * std::sqrt(radicand) + 1.0 - alpha;
  if (!(denominator > 0.0)) return std::nullopt;
  const double mz = (1.0 - beta * alpha * alpha * r2) / denominator;
  const Vec3 ray(m.x(), m.y(), mz);
  if (!(ray.norm() > 0.0)) return std::nullopt;
  return ray.normalized();
}

std::optional<Vec2> project_eucm(const ModelRow& row, const double* p, const Vec3& X) {
  const Intrinsic k = intrinsic(row, p);
  const double alpha = k.extra[0];
  const double beta = k.extra[1];
  const double rho = std::sqrt(beta * (X.x() * X.x() + X.y() * X.y()) + X.z() * X.z());
  const double denominator = alpha * rho + (1.0 - alpha) * X.z();
  if (!(denominator > 0.0)) return std::nullopt;
  // The projection is one-to-one for z > -w rho, w = alpha / (1 - alpha) for alpha <= 1/2, else
  // (1 - alpha) / alpha (Usenko et al., The Double Sphere Camera Model, 2018): beyond it the
  // pixel belongs to another ray.
  const double w = alpha <= 0.5 ? alpha / (1.0 - alpha) : (1.0 - alpha) / alpha;
  if (!(X.z() > -w * rho)) return std::nullopt;
  return Vec2(k.fx * X.x() / denominator + k.cx, k.fy * X.y() / denominator + k.cy);
}

// ---- equirectangular (w, h): longitude 2 pi (u / w - 1/2), latitude pi (1/2 - v / h)

std::optional<Vec3> unproject_equirectangular(const ModelRow&, const double* p, double u,
                                              double v) {
  const double longitude = 2.0 * kPi * (u / p[0] - 0.5);
  const double latitude = kPi * (0.5 - v / p[1]);
  const double c = std::cos(latitude);
  return Vec3(c * std::sin(longitude), -std::sin(latitude), c * std::cos(longitude));
}

std::optional<Vec2> project_equirectangular(const ModelRow&, const double* p, const Vec3& X) {
  const double horizontal = std::hypot(X.x(), X.z());
  if (!(horizontal + std::abs(X.y()) > 0.0)) return std::nullopt;
  const double longitude = std::atan2(X.x(), X.z());
  const double latitude = std::atan2(-X.y(), horizontal);
  return Vec2((longitude / (2.0 * kPi) + 0.5) * p[0], (0.5 - latitude / kPi) * p[1]);
}

using P = CameraProjection;
using M = CameraModel;

// The table. Parameter lists and ids are COLMAP's.
const std::array<ModelRow, 18> kRows = {{
    {{M::kSimplePinhole, 0, "SIMPLE_PINHOLE", "f, cx, cy", 3, P::kPerspective},
     1,
     &no_distortion,
     &unproject_perspective,
     &project_perspective},
    {{M::kPinhole, 1, "PINHOLE", "fx, fy, cx, cy", 4, P::kPerspective},
     2,
     &no_distortion,
     &unproject_perspective,
     &project_perspective},
    {{M::kSimpleRadial, 2, "SIMPLE_RADIAL", "f, cx, cy, k", 4, P::kPerspective},
     1,
     &simple_radial,
     &unproject_perspective,
     &project_perspective},
    {{M::kRadial, 3, "RADIAL", "f, cx, cy, k1, k2", 5, P::kPerspective},
     1,
     &radial,
     &unproject_perspective,
     &project_perspective},
    {{M::kOpenCv, 4, "OPENCV", "fx, fy, cx, cy, k1, k2, p1, p2", 8, P::kPerspective},
     2,
     &opencv,
     &unproject_perspective,
     &project_perspective},
    {{M::kOpenCvFisheye, 5, "OPENCV_FISHEYE", "fx, fy, cx, cy, k1, k2, k3, k4", 8, P::kFisheye},
     2,
     &opencv_fisheye,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kFullOpenCv, 6, "FULL_OPENCV", "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6", 12,
      P::kPerspective},
     2,
     &full_opencv,
     &unproject_perspective,
     &project_perspective},
    {{M::kFov, 7, "FOV", "fx, fy, cx, cy, omega", 5, P::kPerspective},
     2,
     &no_distortion,
     &unproject_fov,
     &project_fov},
    {{M::kSimpleRadialFisheye, 8, "SIMPLE_RADIAL_FISHEYE", "f, cx, cy, k", 4, P::kFisheye},
     1,
     &simple_radial,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kRadialFisheye, 9, "RADIAL_FISHEYE", "f, cx, cy, k1, k2", 5, P::kFisheye},
     1,
     &radial,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kThinPrismFisheye, 10, "THIN_PRISM_FISHEYE",
      "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1", 12, P::kFisheye},
     2,
     &thin_prism,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kRadTanThinPrismFisheye, 11, "RAD_TAN_THIN_PRISM_FISHEYE",
      "fx, fy, cx, cy, k0, k1, k2, k3, k4, k5, p0, p1, s0, s1, s2, s3", 16, P::kFisheye},
     2,
     &rad_tan_thin_prism,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kSimpleDivision, 12, "SIMPLE_DIVISION", "f, cx, cy, k", 4, P::kPerspective},
     1,
     &no_distortion,
     &unproject_division,
     &project_division},
    {{M::kDivision, 13, "DIVISION", "fx, fy, cx, cy, k", 5, P::kPerspective},
     2,
     &no_distortion,
     &unproject_division,
     &project_division},
    {{M::kSimpleFisheye, 14, "SIMPLE_FISHEYE", "f, cx, cy", 3, P::kFisheye},
     1,
     &no_distortion,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kFisheye, 15, "FISHEYE", "fx, fy, cx, cy", 4, P::kFisheye},
     2,
     &no_distortion,
     &unproject_fisheye,
     &project_fisheye},
    {{M::kEucm, 16, "EUCM", "fx, fy, cx, cy, alpha, beta", 6, P::kPerspective},
     2,
     &no_distortion,
     &unproject_eucm,
     &project_eucm},
    {{M::kEquirectangular, 17, "EQUIRECTANGULAR", "w, h", 2, P::kSpherical},
     0,
     &no_distortion,
     &unproject_equirectangular,
     &project_equirectangular},
}};

const ModelRow& row_of(CameraModel model) {
  const auto index = static_cast<std::size_t>(model);
  return index < kRows.size() ? kRows[index] : kRows[1];
}

}  // namespace

const std::vector<CameraModelInfo>& camera_models() {
  static const std::vector<CameraModelInfo> models = [] {
    std::vector<CameraModelInfo> out;
    for (const ModelRow& row : kRows) out.push_back(row.info);
    return out;
  }();
  return models;
}

const CameraModelInfo& camera_model_info(CameraModel model) { return row_of(model).info; }

std::string camera_model_name(CameraModel model) { return row_of(model).info.name; }

std::optional<CameraModel> camera_model_from_name(const std::string& name) {
  for (const ModelRow& row : kRows) {
    if (name == row.info.name) return row.info.model;
  }
  return std::nullopt;
}

std::optional<CameraModel> camera_model_from_id(long long id) {
  for (const ModelRow& row : kRows) {
    if (id == row.info.id) return row.info.model;
  }
  return std::nullopt;
}

std::size_t camera_model_num_params(CameraModel model) { return row_of(model).info.num_params; }

std::string camera_model_list() {
  std::string out;
  for (const ModelRow& row : kRows) {
    if (!out.empty()) out += ", ";
    out += std::string(row.info.name) + " (" + std::to_string(row.info.id) + ")";
  }
  return out;
}

PinholeIntrinsics CameraIntrinsics::pinhole() const {
  const ModelRow& row = row_of(model);
  if (row.num_focal == 0) {
    return {params[0] / (2.0 * kPi), params[1] / kPi, 0.5 * params[0], 0.5 * params[1]};
  }
  const Intrinsic k = intrinsic(row, params.data());
  return {k.fx, k.fy, k.cx, k.cy};
}

std::optional<Eigen::Vector2d> CameraIntrinsics::project_px(const Vec3& p_camera) const {
  if (params.size() != camera_model_num_params(model) || !p_camera.allFinite()) {
    return std::nullopt;
  }
  const ModelRow& row = row_of(model);
  const std::optional<Vec2> px = row.project(row, params.data(), p_camera);
  if (!px || !px->allFinite()) return std::nullopt;
  return px;
}

Eigen::Vector2d CameraIntrinsics::project(const Vec3& p_camera) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return project_px(p_camera).value_or(Vec2(nan, nan));
}

std::optional<Vec3> CameraIntrinsics::unproject(double u_px, double v_px) const {
  if (params.size() != camera_model_num_params(model) || !std::isfinite(u_px) ||
      !std::isfinite(v_px)) {
    return std::nullopt;
  }
  const ModelRow& row = row_of(model);
  const std::optional<Vec3> bearing = row.unproject(row, params.data(), u_px, v_px);
  if (!bearing || !bearing->allFinite()) return std::nullopt;
  return bearing;
}

std::optional<Eigen::Vector2d> CameraIntrinsics::undistort_px(double u_px, double v_px) const {
  const ModelRow& row = row_of(model);
  if (row.info.projection != CameraProjection::kPerspective ||
      params.size() != row.info.num_params) {
    return std::nullopt;
  }
  const Intrinsic k = intrinsic(row, params.data());
  Vec2 x;
  if (row.unproject == &unproject_perspective) {
    // The additive models, as before the table existed (bit for bit): fixed-point iteration.
    const double x0 = (u_px - k.cx) / k.fx;
    const double y0 = (v_px - k.cy) / k.fy;
    double xi = x0;
    double yi = y0;
    bool converged = row.distortion == &no_distortion;
    for (int i = 0; i < 100 && !converged; ++i) {
      const Vec2 d = row.distortion(k.extra, xi, yi);
      const double nx = x0 - d.x();
      const double ny = y0 - d.y();
      if (!std::isfinite(nx) || !std::isfinite(ny)) break;
      converged =
          std::abs(nx - xi) + std::abs(ny - yi) <= 1e-12 * (1.0 + std::abs(nx) + std::abs(ny));
      xi = nx;
      yi = ny;
    }
    if (converged) {
      x = Vec2(xi, yi);
    } else {
      const std::optional<Vec2> newton = invert_distortion(row.distortion, k.extra, Vec2(x0, y0));
      if (!newton) return std::nullopt;
      x = *newton;
    }
  } else {
    const std::optional<Vec3> b = unproject(u_px, v_px);
    if (!b || !(b->z() > 0.0)) return std::nullopt;
    x = Vec2(b->x() / b->z(), b->y() / b->z());
  }
  const Vec2 out(k.fx * x.x() + k.cx, k.fy * x.y() + k.cy);
  if (!out.allFinite()) return std::nullopt;
  return out;
}

bool CameraIntrinsics::is_valid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  const ModelRow& row = row_of(model);
  if (static_cast<std::size_t>(model) >= kRows.size()) {
    return fail("camera model id " + std::to_string(static_cast<int>(model)) + " is unknown");
  }
  const std::size_t expected = row.info.num_params;
  if (params.size() != expected) {
    return fail("camera model " + std::string(row.info.name) + " has " +
                std::to_string(params.size()) + " parameters, expected " +
                std::to_string(expected) + " (" + row.info.params + ")");
  }
  for (std::size_t i = 0; i < params.size(); ++i) {
    if (!std::isfinite(params[i])) {
      return fail("camera parameter " + std::to_string(i) + " is not finite");
    }
  }
  if (width_px < 0 || height_px < 0) return fail("negative image size");
  if (row.num_focal == 0) {
    if (!(params[0] > 0.0) || !(params[1] > 0.0)) {
      return fail(std::string(row.info.name) + " image size w, h must be > 0");
    }
    return true;
  }
  if (model == CameraModel::kEucm) {
    if (!(params[4] >= 0.0 && params[4] <= 1.0)) return fail("EUCM alpha must be in [0, 1]");
    if (!(params[5] > 0.0)) return fail("EUCM beta must be > 0");
  }
  return pinhole().is_valid(why);
}

}  // namespace lmalign
