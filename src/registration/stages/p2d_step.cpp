#include "lmalign/registration/stages/p2d_step.hpp"

#include <cmath>

#include <Eigen/Cholesky>

namespace lmalign {

namespace {

Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0;
  return m;
}

}  // namespace

P2DStep solve_p2d_step(const std::vector<GatedPair>& pairs, const Points3& target_points,
                       const Vec3& pivot_m, double chi2_threshold, const Vec3* up) {
  P2DStep step;
  Mat6 H = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  // Serial sums in pair order: deterministic.
  for (const GatedPair& p : pairs) {
    const Vec3 r = target_points[p.target_index] - p.moved_source_m;
    const double w = 1.0 / (1.0 + p.d2 / chi2_threshold);
    // r(xi) = r - rho + [x - pivot]x phi  ->  J = [-I, [x - pivot]x]
    Eigen::Matrix<double, 3, 6> J;
    J.leftCols<3>() = -Mat3::Identity();
    J.rightCols<3>() = skew(p.moved_source_m - pivot_m);
    const Eigen::Matrix<double, 6, 3> JtO = J.transpose() * p.information;
    H.noalias() += w * JtO * J;
    g.noalias() += w * JtO * r;
    step.chi2 += w * r.dot(p.information * r);
    step.weight_sum += w;
  }
  step.hessian = H;
  if (up == nullptr) {
    if (pairs.size() < 3) return step;
    const Eigen::LDLT<Mat6> ldlt(H);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) return step;
    step.xi = -ldlt.solve(g);
  } else {
    if (pairs.size() < 2) return step;
    // Unknowns (rho, a) with phi = a up.
    Eigen::Matrix<double, 6, 4> B = Eigen::Matrix<double, 6, 4>::Zero();
    B.topLeftCorner<3, 3>() = Mat3::Identity();
    B.block<3, 1>(3, 3) = *up;
    const Eigen::Matrix4d H4 = B.transpose() * H * B;
    const Eigen::Vector4d g4 = B.transpose() * g;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(H4);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) return step;
    step.xi = B * (-ldlt.solve(g4));
    Mat6 H_used = Mat6::Zero();
    H_used = B * H4 * B.transpose();
    step.hessian = H_used;
  }
  step.ok = step.xi.allFinite();
  if (!step.ok) step.xi.setZero();
  return step;
}

Isometry3 apply_step(const Isometry3& T_target_source, const Vec6& xi, const Vec3& pivot_m) {
  const Vec3 rho = xi.head<3>();
  const Vec3 phi = xi.tail<3>();
  const double angle = phi.norm();
  const Mat3 dR =
      angle > 0.0 ? Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix() : Mat3::Identity();
  Isometry3 T = Isometry3::Identity();
  T.linear() = dR * T_target_source.linear();
  T.translation() = dR * (T_target_source.translation() - pivot_m) + pivot_m + rho;
  // Re-orthonormalise (many small steps).
  const Eigen::JacobiSVD<Mat3> svd(T.linear(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  return T;
}

PoseCovariance p2d_covariance(const P2DStep& step, std::size_t num_pairs, const Vec3& pivot_m) {
  PoseCovariance pc;
  pc.num_correspondences = num_pairs;
  const Eigen::FullPivLU<Mat6> lu(step.hessian);
  if (!lu.isInvertible() || num_pairs < 3) return pc;
  const double dof = 3.0 * static_cast<double>(num_pairs) - 6.0;
  // With the weights normalised to mean 1 both chi2 and H scale by n / sum w, which cancels.
  const double s2 = dof > 0.0 ? step.chi2 / dof : 1.0;
  Mat6 A = Mat6::Identity();
  A.block<3, 3>(0, 3) = skew(pivot_m);
  pc.covariance = s2 * A * lu.inverse() * A.transpose();
  pc.covariance = (0.5 * (pc.covariance + pc.covariance.transpose())).eval();
  pc.sigma_m = std::sqrt(s2);
  pc.valid = pc.covariance.allFinite();
  return pc;
}

}  // namespace lmalign
