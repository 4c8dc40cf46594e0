#include "lmalign/registration/similarity.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign {

std::string to_string(ScaleMode mode) { return name_of(kScaleModeNames, mode); }

ScaleMode parse_scale_mode(const std::string& name) {
  return parse_enum(kScaleModeNames, "scale mode", name);
}

ScaleMode resolve_scale_mode(ScaleMode mode, bool source_metric, bool target_metric) {
  if (mode != ScaleMode::kAuto) return mode;
  return source_metric && target_metric ? ScaleMode::kFixed : ScaleMode::kFree;
}

std::optional<Similarity3> umeyama_similarity(const Points3& source, const Points3& target,
                                              const std::vector<double>* weights) {
  if (source.size() != target.size() || (weights != nullptr && weights->size() != source.size())) {
    throw InvalidArgument("umeyama_similarity: sizes differ");
  }
  const std::size_t n = source.size();
  if (n < 3) return std::nullopt;
  auto w = [&](std::size_t i) { return weights != nullptr ? (*weights)[i] : 1.0; };
  double wsum = 0.0;
  Vec3 mu_s = Vec3::Zero(), mu_t = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    wsum += w(i);
    mu_s += w(i) * source[i];
    mu_t += w(i) * target[i];
  }
  if (!(wsum > 0.0)) return std::nullopt;
  mu_s /= wsum;
  mu_t /= wsum;
  // Eqs. 36-38: sigma_s^2 and the cross-covariance Sigma_ts, weighted.
  double var_s = 0.0;
  Mat3 Sigma = Mat3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 a = source[i] - mu_s;
    const Vec3 b = target[i] - mu_t;
    var_s += w(i) * a.squaredNorm();
    Sigma.noalias() += w(i) * b * a.transpose();
  }
  var_s /= wsum;
  Sigma /= wsum;
  if (!(var_s > 0.0)) return std::nullopt;
  const Eigen::JacobiSVD<Mat3> svd(Sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Vec3 S = Vec3::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S[2] = -1.0;
  Similarity3 out;
  out.rigid.linear() = svd.matrixU() * S.asDiagonal() * svd.matrixV().transpose();  // eq. 40
  out.scale = svd.singularValues().dot(S) / var_s;                                  // eq. 42
  out.rigid.translation() = mu_t - out.scale * (out.rigid.linear() * mu_s);         // eq. 41
  if (!(out.scale > 0.0) || !out.matrix().allFinite()) return std::nullopt;
  return out;
}

SimilarityStep solve_similarity_step(const Points3& moved, const Points3& targets,
                                     const std::vector<Mat3>* information,
                                     const std::vector<double>& weights, const Vec3& pivot) {
  const std::size_t n = moved.size();
  if (targets.size() != n || (information != nullptr && information->size() != n) ||
      (!weights.empty() && weights.size() != n)) {
    throw InvalidArgument("solve_similarity_step: sizes differ");
  }
  SimilarityStep step;
  step.num_pairs = n;
  Mat7 H = Mat7::Zero();
  Vec7 g = Vec7::Zero();
  // Serial sums in pair order: deterministic.
  for (std::size_t i = 0; i < n; ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    const Vec3 r = targets[i] - moved[i];
    const Vec3 d = moved[i] - pivot;
    // r(xi) = r - rho + [d]x phi - sigma d.
    Eigen::Matrix<double, 3, 7> J;
    J.leftCols<3>() = -Mat3::Identity();
    J.block<3, 3>(0, 3) = skew(d);
    J.col(6) = -d;
    const Mat3 O = information != nullptr ? (*information)[i] : Mat3::Identity();
    const Eigen::Matrix<double, 7, 3> JtO = J.transpose() * O;
    H.noalias() += w * JtO * J;
    g.noalias() += w * JtO * r;
    step.chi2 += w * r.dot(O * r);
  }
  step.hessian = H;
  if (n < 3) return step;
  const Eigen::LDLT<Mat7> ldlt(H);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) return step;
  step.xi = -ldlt.solve(g);
  step.ok = step.xi.allFinite();
  if (!step.ok) step.xi.setZero();
  return step;
}

Similarity3 similarity_increment(const Vec7& xi, const Vec3& pivot) {
  const Vec3 rho = xi.head<3>();
  const Vec3 phi = xi.segment<3>(3);
  const double angle = phi.norm();
  const Mat3 dR =
      angle > 0.0 ? Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix() : Mat3::Identity();
  Similarity3 S;
  S.scale = std::exp(xi[6]);
  S.rigid.linear() = dR;
  S.rigid.translation() = pivot + rho - S.scale * (dR * pivot);
  return S;
}

std::optional<Mat7> similarity_covariance(const SimilarityStep& step, const Vec3& pivot) {
  const Eigen::FullPivLU<Mat7> lu(step.hessian);
  if (!lu.isInvertible() || step.num_pairs < 3) return std::nullopt;
  const double dof = 3.0 * static_cast<double>(step.num_pairs) - 7.0;
  const double s2 = dof > 0.0 ? step.chi2 / dof : 1.0;
  Mat7 A = Mat7::Identity();
  A.block<3, 3>(0, 3) = skew(pivot);
  A.block<3, 1>(0, 6) = -pivot;
  Mat7 c = s2 * A * lu.inverse() * A.transpose();
  c = 0.5 * (c + c.transpose());
  if (!c.allFinite()) return std::nullopt;
  return c;
}

double initial_scale_from_spacing(double source_spacing, double target_spacing) {
  if (!(source_spacing > 0.0) || !(target_spacing > 0.0)) {
    throw InvalidArgument("initial_scale_from_spacing: spacings must be > 0");
  }
  return std::clamp(target_spacing / source_spacing, 0.1, 10.0);
}

}  // namespace lmalign
