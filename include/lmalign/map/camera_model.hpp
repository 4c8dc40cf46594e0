// Per-image camera intrinsics of maps read from other tools (COLMAP, Bundler): the pinhole models
// and the radial / OpenCV distortion models, with COLMAP's parameter order and equations
// (colmap/src/colmap/sensor/models.h: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV).
// Our own map text format stores no intrinsics; a Frame read from it has none.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/camera.hpp"

namespace lmalign {

/// Camera models, numbered as COLMAP's model ids (cameras.bin stores these ids).
enum class CameraModel : int {
  kSimplePinhole = 0,  ///< f, cx, cy
  kPinhole = 1,        ///< fx, fy, cx, cy
  kSimpleRadial = 2,   ///< f, cx, cy, k
  kRadial = 3,         ///< f, cx, cy, k1, k2
  kOpenCv = 4,         ///< fx, fy, cx, cy, k1, k2, p1, p2
};

/// COLMAP's name of the model ("SIMPLE_PINHOLE", ...).
std::string camera_model_name(CameraModel model);
/// The model of a COLMAP name, or nullopt if it is not one of the five above.
std::optional<CameraModel> camera_model_from_name(const std::string& name);
/// The model of a COLMAP model id, or nullopt if it is not one of the five above.
std::optional<CameraModel> camera_model_from_id(long long id);
/// Number of parameters of the model (3, 4, 4, 5, 8).
std::size_t camera_model_num_params(CameraModel model);

/// Intrinsics of one image. Pixels are raw (distorted) pixels with the origin at the top-left
/// of the image, u right, v down; the camera frame has x right, y down, z forward (metres).
struct CameraIntrinsics {
  CameraModel model = CameraModel::kPinhole;
  /// Image size in pixels (0 if unknown).
  long long width_px = 0;
  long long height_px = 0;
  /// Parameters in COLMAP's order for `model` (pixels for f/c, unitless for distortion).
  std::vector<double> params;

  /// The undistorted pinhole part (fx, fy, cx, cy) of the model.
  PinholeIntrinsics pinhole() const;
  /// Projects a camera-frame point (z > 0) to raw pixels, applying the distortion as COLMAP does:
  /// normalised (x/z, y/z) -> distorted -> f * . + c.
  Eigen::Vector2d project(const Vec3& p_camera) const;
  /// Removes the distortion of a raw pixel: the pixel where the undistorted pinhole() would see
  /// the same ray. Fixed-point iteration on the normalised coordinates (as COLMAP's
  /// IterativeUndistortion), at most 100 steps; nullopt if it does not converge to 1e-12 or
  /// gives a non-finite value. Exact (identity) for the pinhole models.
  std::optional<Eigen::Vector2d> undistort_px(double u_px, double v_px) const;

  /// False, and *why names the problem: parameter count not the model's, a non-finite parameter,
  /// a focal length <= 0, or a negative image size.
  bool is_valid(std::string* why = nullptr) const;
};

}  // namespace lmalign
