// Camera models with distortion, as COLMAP defines them (colmap/src/colmap/sensor/models.h).
#include "lmalign/map/camera_model.hpp"

#include <array>
#include <cmath>

namespace lmalign {

namespace {

struct ModelInfo {
  CameraModel model;
  const char* name;
  std::size_t num_params;
};

constexpr std::array<ModelInfo, 5> kModels = {{
    {CameraModel::kSimplePinhole, "SIMPLE_PINHOLE", 3},
    {CameraModel::kPinhole, "PINHOLE", 4},
    {CameraModel::kSimpleRadial, "SIMPLE_RADIAL", 4},
    {CameraModel::kRadial, "RADIAL", 5},
    {CameraModel::kOpenCv, "OPENCV", 8},
}};

const ModelInfo& info(CameraModel model) {
  for (const ModelInfo& m : kModels) {
    if (m.model == model) return m;
  }
  return kModels[1];
}

/// The distortion offset (du, dv) of normalised coordinates (x, y) (COLMAP's Distortion()).
Eigen::Vector2d distortion(const CameraIntrinsics& k, double x, double y) {
  const std::vector<double>& p = k.params;
  const double x2 = x * x;
  const double y2 = y * y;
  const double r2 = x2 + y2;
  switch (k.model) {
    case CameraModel::kSimpleRadial: {
      const double radial = p[3] * r2;
      return {x * radial, y * radial};
    }
    case CameraModel::kRadial: {
      const double radial = p[3] * r2 + p[4] * r2 * r2;
      return {x * radial, y * radial};
    }
    case CameraModel::kOpenCv: {
      const double radial = p[4] * r2 + p[5] * r2 * r2;
      const double xy = x * y;
      return {x * radial + 2.0 * p[6] * xy + p[7] * (r2 + 2.0 * x2),
              y * radial + 2.0 * p[7] * xy + p[6] * (r2 + 2.0 * y2)};
    }
    default:
      return {0.0, 0.0};
  }
}

}  // namespace

std::string camera_model_name(CameraModel model) { return info(model).name; }

std::optional<CameraModel> camera_model_from_name(const std::string& name) {
  for (const ModelInfo& m : kModels) {
    if (name == m.name) return m.model;
  }
  return std::nullopt;
}

std::optional<CameraModel> camera_model_from_id(long long id) {
  for (const ModelInfo& m : kModels) {
    if (id == static_cast<long long>(m.model)) return m.model;
  }
  return std::nullopt;
}

std::size_t camera_model_num_params(CameraModel model) { return info(model).num_params; }

PinholeIntrinsics CameraIntrinsics::pinhole() const {
  switch (model) {
    case CameraModel::kSimplePinhole:
    case CameraModel::kSimpleRadial:
    case CameraModel::kRadial:
      return {params[0], params[0], params[1], params[2]};
    default:
      return {params[0], params[1], params[2], params[3]};
  }
}

Eigen::Vector2d CameraIntrinsics::project(const Vec3& p_camera) const {
  const PinholeIntrinsics k = pinhole();
  const double x = p_camera.x() / p_camera.z();
  const double y = p_camera.y() / p_camera.z();
  const Eigen::Vector2d d = distortion(*this, x, y);
  return {k.fx_px * (x + d.x()) + k.cx_px, k.fy_px * (y + d.y()) + k.cy_px};
}

std::optional<Eigen::Vector2d> CameraIntrinsics::undistort_px(double u_px, double v_px) const {
  const PinholeIntrinsics k = pinhole();
  const double x0 = (u_px - k.cx_px) / k.fx_px;
  const double y0 = (v_px - k.cy_px) / k.fy_px;
  double x = x0;
  double y = y0;
  bool converged = model == CameraModel::kSimplePinhole || model == CameraModel::kPinhole;
  for (int i = 0; i < 100 && !converged; ++i) {
    const Eigen::Vector2d d = distortion(*this, x, y);
    const double nx = x0 - d.x();
    const double ny = y0 - d.y();
    if (!std::isfinite(nx) || !std::isfinite(ny)) return std::nullopt;
    converged = std::abs(nx - x) + std::abs(ny - y) <= 1e-12 * (1.0 + std::abs(nx) + std::abs(ny));
    x = nx;
    y = ny;
  }
  if (!converged) return std::nullopt;
  const Eigen::Vector2d out(k.fx_px * x + k.cx_px, k.fy_px * y + k.cy_px);
  if (!out.allFinite()) return std::nullopt;
  return out;
}

bool CameraIntrinsics::is_valid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  const std::size_t expected = camera_model_num_params(model);
  if (params.size() != expected) {
    return fail("camera model " + camera_model_name(model) + " has " +
                std::to_string(params.size()) + " parameters, expected " +
                std::to_string(expected));
  }
  for (std::size_t i = 0; i < params.size(); ++i) {
    if (!std::isfinite(params[i])) {
      return fail("camera parameter " + std::to_string(i) + " is not finite");
    }
  }
  if (width_px < 0 || height_px < 0) return fail("negative image size");
  return pinhole().is_valid(why);
}

}  // namespace lmalign
