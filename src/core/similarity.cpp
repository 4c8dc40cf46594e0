#include "lmalign/core/similarity.hpp"

#include <cmath>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign {

Mat4 Similarity3::matrix() const {
  Mat4 M = Mat4::Identity();
  M.topLeftCorner<3, 3>() = scale * rigid.linear();
  M.topRightCorner<3, 1>() = rigid.translation();
  return M;
}

Similarity3 Similarity3::inverse() const {
  Similarity3 out;
  out.scale = 1.0 / scale;
  const Mat3 Rt = rigid.linear().transpose();
  out.rigid.linear() = Rt;
  out.rigid.translation() = -(Rt * rigid.translation()) / scale;
  return out;
}

Similarity3 Similarity3::operator*(const Similarity3& other) const {
  Similarity3 out;
  out.scale = scale * other.scale;
  out.rigid.linear() = rigid.linear() * other.rigid.linear();
  out.rigid.translation() =
      scale * (rigid.linear() * other.rigid.translation()) + rigid.translation();
  return out;
}

Similarity3 similarity_from_matrix(const Mat4& M, const std::string& what) {
  if (!M.allFinite()) throw InvalidArgument(what + ": not finite");
  if (M(3, 0) != 0.0 || M(3, 1) != 0.0 || M(3, 2) != 0.0 || M(3, 3) != 1.0) {
    throw InvalidArgument(what + ": last row must be 0 0 0 1");
  }
  const Mat3 A = M.topLeftCorner<3, 3>();
  const double s = std::cbrt(A.determinant());
  if (!std::isfinite(s) || !(s > 0.0)) {
    throw InvalidArgument(what + ": the scale (cube root of the 3x3 block's determinant) is " +
                          std::to_string(s) + ", expected finite and > 0");
  }
  const Mat3 R = A / s;
  if (!(R * R.transpose()).isApprox(Mat3::Identity(), 1e-6)) {
    throw InvalidArgument(what + ": the 3x3 block is neither a rotation nor a scaled rotation");
  }
  Similarity3 S;
  S.scale = s;
  S.rigid.linear() = R;
  S.rigid.translation() = M.topRightCorner<3, 1>();
  return S;
}

SimilarityError similarity_error(const Similarity3& S_est, const Similarity3& S_true) {
  const TransformError e = transform_error(S_est.rigid, S_true.rigid);
  SimilarityError out;
  out.rotation_deg = e.rotation_deg;
  out.translation_m = e.translation_m;
  out.scale_error = std::abs(S_est.scale / S_true.scale - 1.0);
  return out;
}

}  // namespace lmalign
