// Similarity transforms: p_target = scale * R * p_source + t (Sim(3)), for maps whose lengths
// are in different units (monocular SLAM, structure from motion). As COLMAP's Sim3d
// (`b_from_a`: scale, rotation, translation), stored here as a scale beside a rigid transform.
//
// Frames: S_target_source, p_target = S_target_source * p_source.
#pragma once

#include <string>

#include "lmalign/core/types.hpp"

namespace lmalign {

/// p_target = scale * R * p_source + t, with R = rigid.linear(), t = rigid.translation().
/// `scale` is target units per source unit (> 0).
struct Similarity3 {
  double scale = 1.0;
  Isometry3 rigid = Isometry3::Identity();

  /// The 4x4 matrix [sR t; 0 0 0 1].
  Mat4 matrix() const;
  Vec3 operator*(const Vec3& p) const { return scale * (rigid.linear() * p) + rigid.translation(); }
  /// S^-1: scale 1/s, R^T, -R^T t / s.
  Similarity3 inverse() const;
  /// (this * other)(p) = this(other(p)).
  Similarity3 operator*(const Similarity3& other) const;
};

/// The similarity of a 4x4 matrix [sR t; 0 0 0 1]: s = cbrt(det A) of its 3x3 block A, R = A / s.
/// Throws InvalidArgument (starting with `what`) when an entry is not finite, the last row is not
/// 0 0 0 1, the scale is not finite and > 0, or A / s is not a rotation (orthonormal to 1e-6,
/// det +1): "neither a rotation nor a scaled rotation".
Similarity3 similarity_from_matrix(const Mat4& M, const std::string& what);

/// Error of an estimated similarity against the true one: the rotation and translation errors
/// of geometry.hpp's transform_error (degrees; target units) and the relative scale error
/// |s_est / s_true - 1| (dimensionless).
struct SimilarityError {
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  double scale_error = 0.0;
};
SimilarityError similarity_error(const Similarity3& S_est, const Similarity3& S_true);

}  // namespace lmalign
