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

// Moves a covariance about the pivot to one about the target frame's origin: rho' = rho +
// [pivot]x phi - sigma pivot (the scale's column only in 7 DoF).
template <int N>
Eigen::Matrix<double, N, N> about_origin(const Eigen::Matrix<double, N, N>& c, const Vec3& p) {
  Eigen::Matrix<double, N, N> A = Eigen::Matrix<double, N, N>::Identity();
  A.template block<3, 3>(0, 3) = skew(p);
  if constexpr (N == 7) A.template block<3, 1>(0, 6) = -p;
  const Eigen::Matrix<double, N, N> out = A * c * A.transpose();
  return 0.5 * (out + out.transpose());
}

}  // namespace

std::vector<double> cauchy_weights(const std::vector<GatedPair>& pairs, double scale_d2) {
  std::vector<double> w(pairs.size());
  for (std::size_t i = 0; i < pairs.size(); ++i) w[i] = cauchy_weight(pairs[i].d2 / scale_d2);
  return w;
}

namespace {

void check_basis(const char* what, const std::vector<GatedPair>& pairs, const P2DBasis& basis) {
  if (basis.kind == P2DBasis::Kind::k7 && basis.source_covariances_m2 != nullptr &&
      basis.source_covariances_m2->size() != pairs.size()) {
    throw InvalidArgument(std::string(what) + ": " +
                          std::to_string(basis.source_covariances_m2->size()) +
                          " source covariances for " + std::to_string(pairs.size()) + " pairs");
  }
}

// The scale's part of one pair: its Jacobian column -(x - pivot), and the change of d^2 with
// sigma through the information, d(r^T Omega r)/d sigma = -2 r^T Omega C_s Omega r (C_s the
// source covariance in the target frame, which a scale change multiplies by exp(2 sigma)).
struct ScaleTerms {
  Vec3 J;
  double dd2 = 0.0;
};

ScaleTerms scale_terms(const GatedPair& p, const Vec3& r, const Vec3& pivot_m, const Mat3* C_s) {
  ScaleTerms t;
  t.J = -(p.moved_source_m - pivot_m);
  if (C_s != nullptr) {
    const Vec3 Or = p.information * r;
    t.dd2 = -2.0 * Or.dot(*C_s * Or);
  }
  return t;
}

// The 7-DoF normal equations: the rigid 6x6 as solve_p2d_step's rigid bases sum it, bordered by
// the scale's row and column. The gradient's scale entry includes half the d^2 change through
// the information (g = dE/dxi / 2).
void accumulate_7(const std::vector<GatedPair>& pairs, const Points3& target_points,
                  const Vec3& pivot_m, const std::vector<double>& weights, const P2DBasis& basis,
                  Mat7* H, Vec7* g, P2DStep* step) {
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const GatedPair& p = pairs[i];
    const auto [r, w, J, JtO] =
        pair_terms(p, target_points, pivot_m, weights.empty() ? 1.0 : weights[i]);
    const ScaleTerms st = scale_terms(
        p, r, pivot_m,
        basis.source_covariances_m2 != nullptr ? &(*basis.source_covariances_m2)[i] : nullptr);
    const Vec3 OJs = p.information * st.J;
    H->topLeftCorner<6, 6>().noalias() += w * JtO * J;
    const Vec6 cross = w * (JtO * st.J);
    H->block<6, 1>(0, 6) += cross;
    H->block<1, 6>(6, 0) += cross.transpose();
    (*H)(6, 6) += w * st.J.dot(OJs);
    g->head<6>().noalias() += w * JtO * r;
    (*g)(6) += w * (OJs.dot(r) + 0.5 * st.dd2);
    step->chi2 += w * r.dot(p.information * r);
    step->weight_sum += w;
  }
}

// A system the step may solve: factorised, and of full rank to well within round-off (its
// smallest pivot above 1e-12 of its largest). A pivot of a rank-deficient system is round-off,
// and its sign is chance: a collinear map at an exact pose gave a positive one, a step, and a
// "converged" answer where the same map elsewhere was "degenerate".
template <typename Ldlt>
bool full_rank(const Ldlt& ldlt) {
  if (ldlt.info() != Eigen::Success) return false;
  const auto d = ldlt.vectorD();
  return d.minCoeff() > 1e-12 * d.cwiseAbs().maxCoeff();
}

}  // namespace

P2DStep solve_p2d_step(const std::vector<GatedPair>& pairs, const Points3& target_points,
                       const Vec3& pivot_m, const std::vector<double>& weights,
                       const P2DBasis& basis) {
  check_weights("solve_p2d_step", pairs, weights);
  check_basis("solve_p2d_step", pairs, basis);
  P2DStep step;
  step.dof = basis.dof();
  if (basis.kind == P2DBasis::Kind::k7) {
    Mat7 H = Mat7::Zero();
    Vec7 g = Vec7::Zero();
    accumulate_7(pairs, target_points, pivot_m, weights, basis, &H, &g, &step);
    step.hessian = H;
    if (pairs.size() < 3) return step;
    const Eigen::LDLT<Mat7> ldlt(H);
    if (!full_rank(ldlt)) return step;
    step.xi = -ldlt.solve(g);
    step.ok = step.xi.allFinite();
    if (!step.ok) step.xi.setZero();
    return step;
  }
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
  step.hessian.topLeftCorner<6, 6>() = H;
  Vec6 xi = Vec6::Zero();
  if (basis.kind == P2DBasis::Kind::k6) {
    if (pairs.size() < 3) return step;
    const Eigen::LDLT<Mat6> ldlt(H);
    if (!full_rank(ldlt)) return step;
    xi = -ldlt.solve(g);
  } else {
    if (pairs.size() < 2) return step;
    // Unknowns (rho, a) with phi = a up.
    Eigen::Matrix<double, 6, 4> B = Eigen::Matrix<double, 6, 4>::Zero();
    B.topLeftCorner<3, 3>() = Mat3::Identity();
    B.block<3, 1>(3, 3) = basis.up;
    const Eigen::Matrix4d H4 = B.transpose() * H * B;
    const Eigen::Vector4d g4 = B.transpose() * g;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(H4);
    if (!full_rank(ldlt)) return step;
    xi = B * (-ldlt.solve(g4));
    step.hessian.topLeftCorner<6, 6>() = B * H4 * B.transpose();
  }
  step.ok = xi.allFinite();
  if (step.ok) step.xi.head<6>() = xi;
  return step;
}

Isometry3 apply_step(const Isometry3& T_target_source, const Vec7& xi, const Vec3& pivot_m,
                     double* scale) {
  const Vec3 rho = xi.head<3>();
  const Vec3 phi = xi.segment<3>(3);
  const double angle = phi.norm();
  const Mat3 dR =
      angle > 0.0 ? Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix() : Mat3::Identity();
  Isometry3 T = Isometry3::Identity();
  T.linear() = dR * T_target_source.linear();
  if (xi(6) == 0.0) {
    T.translation() = dR * (T_target_source.translation() - pivot_m) + pivot_m + rho;
    if (scale != nullptr) *scale = 1.0;
  } else {
    // p_target = s dR (T p - pivot) + pivot + rho = [dR R] (s p) + s dR (t - pivot) + pivot + rho.
    const double s = std::exp(xi(6));
    T.translation() = s * (dR * (T_target_source.translation() - pivot_m)) + pivot_m + rho;
    if (scale != nullptr) *scale = s;
  }
  // Re-orthonormalise (many small steps).
  const Eigen::JacobiSVD<Mat3> svd(T.linear(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  return T;
}

namespace {

void set_scale_covariance(PoseCovariance* pc, const Mat7& c7) {
  pc->has_scale = true;
  pc->covariance_7x7 = c7;
  pc->covariance = c7.topLeftCorner<6, 6>();
}

}  // namespace

PoseCovariance p2d_covariance(const P2DStep& step, std::size_t num_pairs, const Vec3& pivot_m) {
  PoseCovariance pc;
  pc.num_correspondences = num_pairs;
  if (num_pairs < 3) return pc;
  // (The 4-DoF step keeps the 6-DoF variance factor, as it always has.)
  const double dof = 3.0 * static_cast<double>(num_pairs) - (step.dof == 7 ? 7.0 : 6.0);
  // With the weights normalised to mean 1 both chi2 and H scale by n / sum w, which cancels.
  const double s2 = dof > 0.0 ? step.chi2 / dof : 1.0;
  if (step.dof == 7) {
    const Eigen::FullPivLU<Mat7> lu(step.hessian);
    if (!lu.isInvertible()) return pc;
    set_scale_covariance(&pc, about_origin<7>(s2 * lu.inverse(), pivot_m));
  } else {
    const Eigen::FullPivLU<Mat6> lu(step.hessian_6x6());
    if (!lu.isInvertible()) return pc;
    pc.covariance = about_origin<6>(s2 * lu.inverse(), pivot_m);
  }
  pc.sigma_m = std::sqrt(s2);
  pc.valid = pc.covariance.allFinite() && (!pc.has_scale || pc.covariance_7x7.allFinite());
  return pc;
}

namespace {

// The cluster-robust covariance in N unknowns (6: rigid, 7: with the scale); see the header.
template <int N>
PoseCovariance cluster_covariance(const std::vector<GatedPair>& pairs, const Points3& target_points,
                                  const Vec3& pivot_m, const std::vector<double>& weights,
                                  double block_m, const P2DBasis& basis) {
  using MatN = Eigen::Matrix<double, N, N>;
  using VecN = Eigen::Matrix<double, N, 1>;
  PoseCovariance pc;
  const std::size_t n = pairs.size();
  pc.num_correspondences = n;
  if (n < 3) return pc;
  // H, chi2 and the score of each block, serially in pair order (deterministic); blocks in an
  // ordered map.
  MatN H = MatN::Zero();
  double chi2 = 0.0;
  std::map<std::array<long long, 3>, VecN> blocks;
  for (std::size_t i = 0; i < n; ++i) {
    const GatedPair& p = pairs[i];
    const auto [r, w, J, JtO] =
        pair_terms(p, target_points, pivot_m, weights.empty() ? 1.0 : weights[i]);
    VecN g;
    if constexpr (N == 6) {
      H.noalias() += w * JtO * J;
      g = w * JtO * r;
    } else {
      const ScaleTerms st = scale_terms(
          p, r, pivot_m,
          basis.source_covariances_m2 != nullptr ? &(*basis.source_covariances_m2)[i] : nullptr);
      Eigen::Matrix<double, 3, 7> J7;
      J7.leftCols<6>() = J;
      J7.col(6) = st.J;
      const Eigen::Matrix<double, 7, 3> J7tO = J7.transpose() * p.information;
      H.noalias() += w * J7tO * J7;
      g = w * J7tO * r;
      g(6) += w * 0.5 * st.dd2;
    }
    chi2 += w * r.dot(p.information * r);
    const Vec3 cell = (p.moved_source_m / block_m).array().floor();
    if (!cell.allFinite()) return pc;
    const std::array<long long, 3> key{static_cast<long long>(cell.x()),
                                       static_cast<long long>(cell.y()),
                                       static_cast<long long>(cell.z())};
    auto it = blocks.find(key);
    if (it == blocks.end()) {
      blocks.emplace(key, g);
    } else {
      it->second += g;
    }
  }
  const Eigen::FullPivLU<MatN> lu(H);
  if (!lu.isInvertible()) return pc;
  const MatN H_inv = lu.inverse();
  const MatN model = 0.5 * (H_inv + H_inv.transpose());
  MatN cov = model;
  if (blocks.size() >= 2) {
    MatN B = MatN::Zero();
    for (const auto& kv : blocks) B.noalias() += kv.second * kv.second.transpose();
    const double G = static_cast<double>(blocks.size());
    B *= G / (G - 1.0);
    const MatN S = H_inv * B * H_inv.transpose();
    // max(model, S) in the Loewner order: whiten by the model, raise eigenvalues below 1.
    cov = covariance_max(model, S);
  }
  if constexpr (N == 6) {
    pc.covariance = about_origin<6>(cov, pivot_m);
  } else {
    set_scale_covariance(&pc, about_origin<7>(cov, pivot_m));
  }
  const double dof = 3.0 * static_cast<double>(n) - static_cast<double>(N);
  pc.sigma_m = std::sqrt(chi2 / dof);
  pc.valid = pc.covariance.allFinite() && (!pc.has_scale || pc.covariance_7x7.allFinite());
  if (!pc.valid) {
    pc.covariance.setZero();
    pc.covariance_7x7.setZero();
  }
  return pc;
}

}  // namespace

PoseCovariance p2d_cluster_covariance(const std::vector<GatedPair>& pairs,
                                      const Points3& target_points, const Vec3& pivot_m,
                                      const std::vector<double>& weights, double block_m,
                                      const P2DBasis& basis) {
  if (!(block_m > 0.0) || !std::isfinite(block_m)) {
    throw InvalidArgument("p2d_cluster_covariance: block_m must be > 0 and finite");
  }
  check_weights("p2d_cluster_covariance", pairs, weights);
  check_basis("p2d_cluster_covariance", pairs, basis);
  if (basis.kind == P2DBasis::Kind::k4) {
    throw InvalidArgument("p2d_cluster_covariance: the 4-DoF basis has no cluster covariance");
  }
  if (basis.kind == P2DBasis::Kind::k7) {
    return cluster_covariance<7>(pairs, target_points, pivot_m, weights, block_m, basis);
  }
  return cluster_covariance<6>(pairs, target_points, pivot_m, weights, block_m, basis);
}

}  // namespace lmalign
