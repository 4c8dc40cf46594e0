// Per-image camera intrinsics of maps read from other tools (COLMAP, Bundler, stella_vslam): one
// table of camera models, in the style of COLMAP's (colmap/src/colmap/sensor/models.h): each row
// gives the model's name, COLMAP model id, parameter names, and the functions that project a
// camera-frame point to a raw pixel and unproject a raw pixel to a unit bearing vector. Every
// model COLMAP writes (ids 0-17) is a row; stella_vslam's four models are rows of it too
// (perspective = PINHOLE / OPENCV / FULL_OPENCV, fisheye = OPENCV_FISHEYE, equirectangular =
// EQUIRECTANGULAR, radial_division = DIVISION: docs/map-format.md, "Camera models").
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
  kSimplePinhole = 0,            ///< f, cx, cy
  kPinhole = 1,                  ///< fx, fy, cx, cy
  kSimpleRadial = 2,             ///< f, cx, cy, k
  kRadial = 3,                   ///< f, cx, cy, k1, k2
  kOpenCv = 4,                   ///< fx, fy, cx, cy, k1, k2, p1, p2
  kOpenCvFisheye = 5,            ///< fx, fy, cx, cy, k1, k2, k3, k4
  kFullOpenCv = 6,               ///< fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6
  kFov = 7,                      ///< fx, fy, cx, cy, omega
  kSimpleRadialFisheye = 8,      ///< f, cx, cy, k
  kRadialFisheye = 9,            ///< f, cx, cy, k1, k2
  kThinPrismFisheye = 10,        ///< fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1
  kRadTanThinPrismFisheye = 11,  ///< fx, fy, cx, cy, k0..k5, p0, p1, s0..s3
  kSimpleDivision = 12,          ///< f, cx, cy, k
  kDivision = 13,                ///< fx, fy, cx, cy, k
  kSimpleFisheye = 14,           ///< f, cx, cy
  kFisheye = 15,                 ///< fx, fy, cx, cy
  kEucm = 16,                    ///< fx, fy, cx, cy, alpha, beta
  kEquirectangular = 17,         ///< w, h
};

/// How a model maps rays to its image.
enum class CameraProjection {
  /// Pinhole projection x/z, y/z, then a deformation of that plane (distortion): rays in front
  /// of the camera only, except for the division and EUCM models, whose unprojection can
  /// give rays at or beyond 90 degrees from the axis.
  kPerspective,
  /// Equidistant fisheye: the angle theta from the optical axis, then a deformation of
  /// (theta cos phi, theta sin phi). Rays up to 180 degrees from the axis.
  kFisheye,
  /// A full sphere (equirectangular panorama): every direction.
  kSpherical,
};

/// One row of the camera model table.
struct CameraModelInfo {
  CameraModel model;
  /// COLMAP's model id and name ("OPENCV_FISHEYE").
  int id;
  const char* name;
  /// COLMAP's parameter list, comma-separated ("fx, fy, cx, cy, k1, k2, k3, k4").
  const char* params;
  std::size_t num_params;
  CameraProjection projection;
};

/// Every model, in id order (ids 0-17).
const std::vector<CameraModelInfo>& camera_models();
/// The row of `model`.
const CameraModelInfo& camera_model_info(CameraModel model);
/// COLMAP's name of the model ("SIMPLE_PINHOLE", ...).
std::string camera_model_name(CameraModel model);
/// The model of a COLMAP name, or nullopt if no row has it.
std::optional<CameraModel> camera_model_from_name(const std::string& name);
/// The model of a COLMAP model id, or nullopt if no row has it.
std::optional<CameraModel> camera_model_from_id(long long id);
/// Number of parameters of the model.
std::size_t camera_model_num_params(CameraModel model);
/// The known names, for error messages: "SIMPLE_PINHOLE (0), PINHOLE (1), ..., EQUIRECTANGULAR
/// (17)".
std::string camera_model_list();

/// Intrinsics of one image. Pixels are raw (distorted) pixels with the origin at the top-left
/// corner of the image, u right, v down, unless centred_pixels; the camera frame has x right,
/// y down, z forward.
struct CameraIntrinsics {
  CameraModel model = CameraModel::kPinhole;
  /// Image size in pixels (0 if unknown).
  long long width_px = 0;
  long long height_px = 0;
  /// Parameters in COLMAP's order for `model` (pixels for f/c, unitless for distortion; the
  /// image width and height in pixels for EQUIRECTANGULAR).
  std::vector<double> params;
  /// True when the pixels are relative to the image centre (v still down) because the image
  /// size is unknown: Bundler read without an image size (the principal point is then 0, 0).
  /// Outputs that store top-left pixels (our map text format, COLMAP) refuse such a frame.
  bool centred_pixels = false;

  /// The pinhole part (fx, fy, cx, cy) of a perspective or fisheye model: its focal lengths and
  /// principal point. EQUIRECTANGULAR has none: the pixels per radian at the equator, (w/2π,
  /// h/π), and the image centre.
  PinholeIntrinsics pinhole() const;
  /// Projects a camera-frame point to raw pixels, as COLMAP's ImgFromCam does for the model.
  /// Perspective models need z > 0 (the division and EUCM models: a point their projection
  /// reaches); fisheye models take any point off the backward axis; EQUIRECTANGULAR any non-zero
  /// point. nullopt if the point cannot be projected or the result is not finite.
  std::optional<Eigen::Vector2d> project_px(const Vec3& p_camera) const;
  /// project_px(), or (NaN, NaN) when the point cannot be projected.
  Eigen::Vector2d project(const Vec3& p_camera) const;
  /// The unit bearing vector (camera frame) of a raw pixel: the inverse of project_px(). Models
  /// whose distortion has no closed-form inverse invert it iteratively (fixed-point iteration on
  /// the distortion, as COLMAP's IterativeUndistortion, then Newton if that does not converge).
  /// nullopt if the pixel has no ray (outside the model's domain, no convergence, not finite).
  std::optional<Vec3> unproject(double u_px, double v_px) const;
  /// Removes the distortion of a raw pixel of a perspective model: the pixel where the
  /// undistorted pinhole() would see the same ray. nullopt for other models, for a ray not in
  /// front of the camera, or when the inversion fails. Exact (identity) for the pinhole models;
  /// for SIMPLE_RADIAL, RADIAL and OPENCV a fixed-point iteration on the normalised coordinates
  /// (as COLMAP's IterativeUndistortion), at most 100 steps to 1e-12.
  std::optional<Eigen::Vector2d> undistort_px(double u_px, double v_px) const;

  /// False, and *why names the problem: parameter count not the model's, a non-finite parameter,
  /// a focal length <= 0, an EQUIRECTANGULAR size <= 0, EUCM alpha outside [0, 1] or beta <= 0,
  /// a negative image size.
  bool is_valid(std::string* why = nullptr) const;
};

}  // namespace lmalign
