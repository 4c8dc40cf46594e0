#include "lmalign/registration/stages/p2d_step.hpp"

#include <array>
#include <cmath>
#include <map>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

namespace {

// Pair i's Jacobian about the pivot: r(xi) = r - rho + [x - pivot]x phi.
Eigen::Matrix<double, 3, 6> pair_jacobian(const GatedPair& p, const Vec3& pivot_m) {
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>() = -Mat3::Identity();
  J.rightCols<3>() = skew(p.moved_source_m - pivot_m);
  return J;
}

void check_weights(const char* what, const std::vector<GatedPair>& pairs,
                   const std::vector<double>& weights) {
  if (!weights.empty() && weights.size() != pairs.size()) {
    throw InvalidArgument(std::string(what) + ": " + std::to_string(weights.size()) +
                          " weights for " + std::to_string(pairs.size()) + " pairs");
  }
}

// What one pair adds to the normal equations: residual, weight, Jacobian and J^T S^-1.
struct PairTerms {
  Vec3 r;
  double w;
  Eigen::Matrix<double, 3, 6> J;
  Eigen::Matrix<double, 6, 3> JtO;
};

PairTerms pair_terms(const GatedPair& p, const Points3& target_points, const Vec3& pivot_m,
                     double weight) {
  PairTerms t;
  t.r = target_points[p.target_index] - p.moved_source_m;
  t.w = weight;
  t.J = pair_jacobian(p, pivot_m);
  t.JtO = t.J.transpose() * p.information;
  return t;
}

// Moves a covariance about the pivot to one about the target frame's origin (p2d_covariance).
Mat6 about_origin(const Mat6& cov_about_pivot, const Vec3& pivot_m) {
  Mat6 A = Mat6::Identity();
  A.block<3, 3>(0, 3) = skew(pivot_m);
  const Mat6 c = A * cov_about_pivot * A.transpose();
  return 0.5 * (c + c.transpose());
}

}  // namespace

std::vector<double> cauchy_weights(const std::vector<GatedPair>& pairs, double scale_d2) {
  std::vector<double> w(pairs.size());
  for (std::size_t i = 0; i < pairs.size(); ++i) w[i] = cauchy_weight(pairs[i].d2 / scale_d2);
  return w;
}

P2DStep solve_p2d_step(const std::vector<GatedPair>& pairs, const Points3& target_points,
                       const Vec3& pivot_m, const std::vector<double>& weights, const Vec3* up) {
  check_weights("solve_p2d_step", pairs, weights);
  P2DStep step;
  Mat6 H = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  // Serial sums in pair order: deterministic.
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const GatedPair& p = pairs[i];
    const auto [r, w, J, JtO] =
        pair_terms(p, target_points, pivot_m, weights.empty() ? 1.0 : weights[i]);
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
  pc.covariance = about_origin(s2 * lu.inverse(), pivot_m);
  pc.sigma_m = std::sqrt(s2);
  pc.valid = pc.covariance.allFinite();
  return pc;
}

PoseCovariance p2d_cluster_covariance(const std::vector<GatedPair>& pairs,
                                      const Points3& target_points, const Vec3& pivot_m,
                                      const std::vector<double>& weights, double block_m) {
  if (!(block_m > 0.0) || !std::isfinite(block_m)) {
    throw InvalidArgument("p2d_cluster_covariance: block_m must be > 0 and finite");
  }
  check_weights("p2d_cluster_covariance", pairs, weights);
  PoseCovariance pc;
  const std::size_t n = pairs.size();
  pc.num_correspondences = n;
  if (n < 3) return pc;
  // H, chi2 and the score of each block, serially in pair order (deterministic); blocks in an
  // ordered map.
  Mat6 H = Mat6::Zero();
  double chi2 = 0.0;
  std::map<std::array<long long, 3>, Vec6> blocks;
  for (std::size_t i = 0; i < n; ++i) {
    const GatedPair& p = pairs[i];
    const auto [r, w, J, JtO] =
        pair_terms(p, target_points, pivot_m, weights.empty() ? 1.0 : weights[i]);
    H.noalias() += w * JtO * J;
    chi2 += w * r.dot(p.information * r);
    const Vec3 cell = (p.moved_source_m / block_m).array().floor();
    if (!cell.allFinite()) return pc;
    const std::array<long long, 3> key{static_cast<long long>(cell.x()),
                                       static_cast<long long>(cell.y()),
                                       static_cast<long long>(cell.z())};
    const Vec6 g = w * JtO * r;
    auto it = blocks.find(key);
    if (it == blocks.end()) {
      blocks.emplace(key, g);
    } else {
      it->second += g;
    }
  }
  const Eigen::FullPivLU<Mat6> lu(H);
  if (!lu.isInvertible()) return pc;
  const Mat6 H_inv = lu.inverse();
  const Mat6 model = 0.5 * (H_inv + H_inv.transpose());
  Mat6 cov = model;
  if (blocks.size() >= 2) {
    Mat6 B = Mat6::Zero();
    for (const auto& kv : blocks) B.noalias() += kv.second * kv.second.transpose();
    const double G = static_cast<double>(blocks.size());
    B *= G / (G - 1.0);
    const Mat6 S = H_inv * B * H_inv.transpose();
    // max(model, S) in the Loewner order: whiten by the model, raise eigenvalues below 1.
    cov = covariance_max(model, S);
  }
  pc.covariance = about_origin(cov, pivot_m);
  const double dof = 3.0 * static_cast<double>(n) - 6.0;
  pc.sigma_m = std::sqrt(chi2 / dof);
  pc.valid = pc.covariance.allFinite();
  if (!pc.valid) pc.covariance.setZero();
  return pc;
}

}  // namespace lmalign
