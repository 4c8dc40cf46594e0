// Re-estimating a landmark from pixel observations alone (method.md §6, `split --retriangulate`):
// linear DLT triangulation, Gauss-Newton refinement of the reprojection error with the pinhole
// intrinsics, and the covariance (J^T J)^-1 * sigma^2 from the final normal matrix. Cameras of
// any model enter as views along their pixels' bearing vectors (make_pixel_view()).
#pragma once

#include <optional>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/camera.hpp"
#include "lmalign/map/camera_model.hpp"

namespace lmalign {

/// One view of a point: the camera pose camera-to-world and the pixel seen in it.
struct PixelView {
  Isometry3 T_world_camera;
  double u_px = 0.0;
  double v_px = 0.0;
  /// This view's pinhole intrinsics (undistorted pixels); nullopt uses
  /// TriangulationOptions::intrinsics (maps whose images share one camera).
  std::optional<PinholeIntrinsics> intrinsics;
};

/// The view of a raw pixel seen by a camera with pose T_world_camera and, if given, its own
/// intrinsics (any model of camera_model.hpp). Every view is a pinhole camera looking along the
/// pixel's ray, so that triangulate() serves every model with one code path:
///   - no intrinsics: the raw pixel, with no intrinsics of its own (TriangulationOptions::
///     intrinsics apply);
///   - SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV: the camera itself, with the
///     undistorted pixel (CameraIntrinsics::undistort_px) and the pinhole part: pixel noise is
///     taken on the undistorted pixel, as for every map read before the other models existed;
///   - every other model (fisheye, FOV, division, EUCM, FULL_OPENCV, equirectangular):
///     make_bearing_view().
/// nullopt if the intrinsics are invalid or the pixel has no ray (the undistortion does not
/// converge, a pixel outside the model's domain).
std::optional<PixelView> make_pixel_view(const Isometry3& T_world_camera,
                                         const std::optional<CameraIntrinsics>& camera, double u_px,
                                         double v_px);

/// The view of a raw pixel from its bearing vector b (CameraIntrinsics::unproject): a virtual
/// pinhole camera at the same centre whose optical axis is b, observing the pixel (0, 0). Its
/// axes and focal lengths are the singular vectors and inverse singular values of
/// A = d(tangent coordinates)/d(pixel), the model's local resolution measured by central
/// differences (1e-3 px) of its unprojection, so that isotropic raw pixel noise sigma is
/// isotropic noise sigma in the virtual pixels, to first order, whatever the distortion: the
/// reprojection residual of triangulate() becomes the angular error of the ray, weighted by
/// the model's pixels per radian in each direction. Rays up to 180 degrees from the camera's
/// axis are served (fisheye and equirectangular cameras). nullopt if the intrinsics are invalid
/// or the pixel or its neighbours have no ray.
std::optional<PixelView> make_bearing_view(const Isometry3& T_world_camera,
                                           const CameraIntrinsics& camera, double u_px,
                                           double v_px);

struct TriangulationOptions {
  PinholeIntrinsics intrinsics = PinholeIntrinsics::tum_fr1();
  /// Pixel noise standard deviation for the covariance, pixels.
  double pixel_sigma_px = 1.0;
  /// Gauss-Newton iterations at most (0: the DLT point, with its covariance).
  int max_iterations = 20;
};

struct TriangulatedPoint {
  Vec3 p_world = Vec3::Zero();       ///< metres
  Mat3 cov_world_m2 = Mat3::Zero();  ///< (J^T J)^-1 sigma^2, m^2
  double max_parallax_deg = 0.0;     ///< largest angle between two viewing rays, degrees
  double rms_reprojection_px = 0.0;  ///< sqrt(mean over views of |residual|^2), after refinement
};

/// Triangulates from >= 2 views: DLT on normalised image coordinates (2N x 4, SVD), then
/// Gauss-Newton on the pixel reprojection error in world coordinates, stopping after
/// max_iterations or when the step is below 1e-12 (1 + |p|) m. cov = (J^T J)^-1 sigma^2 with J the
/// 2N x 3 Jacobian of the pixel residuals wrt the world point at the final estimate, computed
/// through the eigendecomposition of J^T J: symmetric positive definite at every accepted
/// condition number.
/// Returns nullopt if fewer than 2 views, if the point is behind a camera (z <= 0 in its frame),
/// if J^T J is singular or ill-conditioned (lambda_min / lambda_max <= 1e-12, e.g. zero
/// parallax), if the intrinsics (shared or per view) or sigma are invalid, or if any input or
/// result is not finite.
std::optional<TriangulatedPoint> triangulate(const std::vector<PixelView>& views,
                                             const TriangulationOptions& options = {});

}  // namespace lmalign
