// Pinhole camera intrinsics (no distortion: the map's pixels fit a pure pinhole, method.md §1).
#pragma once

#include <string>

#include "lmalign/core/types.hpp"

namespace lmalign {

struct PinholeIntrinsics {
  double fx_px = 517.3;
  double fy_px = 516.5;
  double cx_px = 318.6;
  double cy_px = 255.3;

  /// TUM RGB-D freiburg1 (the default; the values of the real map).
  static PinholeIntrinsics tum_fr1() { return {517.3, 516.5, 318.6, 255.3}; }

  /// Projects a point in the camera frame (z forward, metres) to pixels (u right, v down).
  Eigen::Vector2d project(const Vec3& p_camera) const {
    return {fx_px * p_camera.x() / p_camera.z() + cx_px,
            fy_px * p_camera.y() / p_camera.z() + cy_px};
  }
  /// Unit-depth ray (x, y, 1) in the camera frame through pixel (u, v).
  Vec3 unproject(double u_px, double v_px) const {
    return {(u_px - cx_px) / fx_px, (v_px - cy_px) / fy_px, 1.0};
  }

  /// Parses "fx,fy,cx,cy" (pixels). Throws InvalidArgument naming the text on bad input.
  static PinholeIntrinsics parse(const std::string& text);
  /// True if all four values are finite and fx, fy > 0.
  bool is_valid(std::string* why = nullptr) const;
};

}  // namespace lmalign
