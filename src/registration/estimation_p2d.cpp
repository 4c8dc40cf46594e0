#include "lmalign/registration/estimation_p2d.hpp"

#include <cmath>
#include <cstdio>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign {

namespace {

using Mat36 = Eigen::Matrix<double, 3, 6>;
using Vec6d = Eigen::Matrix<double, 6, 1>;

Mat3 skew(const Vec3& v) {
  Mat3 S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

Mat3 exp_so3(const Vec3& phi) {
  const double angle = phi.norm();
  if (angle < 1e-300) return Mat3::Identity();
  return Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
}

/// Smallest eigenvalue of H over its largest below this: singular normal equations.
constexpr double kSingularRatio = 1e-12;
/// Step halvings tried before a Gauss-Newton iteration gives up.
constexpr int kMaxHalvings = 8;
/// The smallest covariance floor accepted (1 nm): its inverse square, 1e18 m^-2, keeps Omega
/// and the normal equations far inside the double range (a floor whose square underflows
/// would let zero covariances give Omega = 1/0).
constexpr double kMinCovarianceFloorM = 1e-9;
/// A pair's combined covariance M whose trace is at most this times floor^2 (so that its
/// condition number is at most about this) is inverted in closed form (cofactors).
constexpr double kClosedFormTraceRatio = 1e8;

/// The information matrix Omega = M^-1 of a pair, M = C_target + R C_source R^T + floor^2 I
/// (symmetric; m^2, so Omega in m^-2). Within kClosedFormTraceRatio, Eigen's closed-form 3x3
/// inverse, accurate there for PSD covariances. Beyond (variances of thousands of m^2 and more:
/// a landmark seen without parallax), cofactors lose every digit: at a condition number of 4e18
/// the estimate came out NaN (docs/robustness.md). There, and wherever the closed
/// form is not a positive diagonal (covariances that are not PSD, against the contract), Omega =
/// V diag(1 / max(lambda, floor^2)) V^T from the symmetric eigendecomposition, positive definite
/// by construction: the pair carries no information along its huge axes. A non-finite M
/// (entries beyond the double range after the sum) carries none at all: Omega = 0.
Mat3 information_per_m2(const Mat3& M, double floor2) {
  if (!M.allFinite()) return Mat3::Zero();
  if (M.trace() <= kClosedFormTraceRatio * floor2) {
    const Mat3 closed_form = M.inverse();
    if (closed_form.allFinite() && closed_form.diagonal().minCoeff() > 0.0) return closed_form;
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> es(M);
  if (es.info() != Eigen::Success) return Mat3::Zero();
  const Vec3 inverse_eigenvalues = es.eigenvalues().cwiseMax(floor2).cwiseInverse();
  return es.eigenvectors() * inverse_eigenvalues.asDiagonal() * es.eigenvectors().transpose();
}

}  // namespace

bool PointToDistributionOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (max_iterations < 0) {
    return fail("max_iterations = " + std::to_string(max_iterations) + " (expected >= 0)");
  }
  if (!(step_tolerance >= 0.0) || !std::isfinite(step_tolerance)) {
    return fail("step_tolerance = " + std::to_string(step_tolerance) + " (expected finite >= 0)");
  }
  if (!(covariance_floor_m >= kMinCovarianceFloorM) || !std::isfinite(covariance_floor_m)) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "covariance_floor_m = %g (expected finite, >= %g m)",
                  covariance_floor_m, kMinCovarianceFloorM);
    return fail(buf);
  }
  return true;
}

PointToDistributionResult estimate_point_to_distribution(
    const Points3& source_points, const Points3& target_points,
    const Correspondences& correspondences, const std::vector<Mat3>& source_covariances_m2,
    const std::vector<Mat3>& target_covariances_m2, const std::vector<double>* weights,
    const PointToDistributionOptions& options, const Isometry3& T_init) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("point-to-distribution options: " + why);
  if (source_covariances_m2.size() != source_points.size()) {
    throw InvalidArgument("point-to-distribution: " + std::to_string(source_covariances_m2.size()) +
                          " source covariances for " + std::to_string(source_points.size()) +
                          " source points");
  }
  if (target_covariances_m2.size() != target_points.size()) {
    throw InvalidArgument("point-to-distribution: " + std::to_string(target_covariances_m2.size()) +
                          " target covariances for " + std::to_string(target_points.size()) +
                          " target points");
  }
  const std::size_t n = correspondences.size();
  if (weights != nullptr && weights->size() != n) {
    throw InvalidArgument("point-to-distribution: " + std::to_string(weights->size()) +
                          " weights for " + std::to_string(n) + " correspondences");
  }
  if (!is_finite(T_init)) throw InvalidArgument("point-to-distribution: T_init is not finite");
  double wsum = 0.0;
  std::size_t n_used = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Correspondence& c = correspondences[i];
    if (c.source_index >= source_points.size() || c.target_index >= target_points.size()) {
      throw InvalidArgument("point-to-distribution: correspondence " + std::to_string(i) +
                            " has an index out of range");
    }
    if (!source_covariances_m2[c.source_index].allFinite() ||
        !target_covariances_m2[c.target_index].allFinite()) {
      throw InvalidArgument("point-to-distribution: correspondence " + std::to_string(i) +
                            " has a non-finite covariance");
    }
    const double w = weights != nullptr ? (*weights)[i] : 1.0;
    if (!(w >= 0.0) || !std::isfinite(w)) {
      throw InvalidArgument("point-to-distribution: weight " + std::to_string(i) +
                            " must be finite and >= 0");
    }
    wsum += w;
    if (w > 0.0) ++n_used;
  }
  if (n > 0 && !(wsum > 0.0)) {
    throw InvalidArgument("point-to-distribution: the weights sum to zero");
  }

  PointToDistributionResult out;
  out.T_target_source = T_init;
  out.num_correspondences = n;
  if (n_used < 3) {
    out.degenerate = true;
    return out;
  }
  const double norm = static_cast<double>(n) / wsum;  // weights to mean 1
  const double floor2 = options.covariance_floor_m * options.covariance_floor_m;

  Isometry3 T = T_init;
  std::vector<Vec3> x(n);
  std::vector<Mat3> omega(n);
  // One linearisation at T: the moved points, the information matrices, H and g about the
  // weighted centroid c of the moved points (conditioning far from the origin), and chi2.
  Mat6 H;
  Vec6d g;
  Vec3 c;
  double chi2 = 0.0;
  auto linearise = [&]() {
    const Mat3 R = T.linear();
    c.setZero();
    for (std::size_t i = 0; i < n; ++i) {
      const double w = weights != nullptr ? (*weights)[i] * norm : 1.0;
      x[i] = T * source_points[correspondences[i].source_index];
      c += w * x[i];
    }
    c /= static_cast<double>(n);  // normalised weights sum to n
    H.setZero();
    g.setZero();
    chi2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const Correspondence& cr = correspondences[i];
      const double w = weights != nullptr ? (*weights)[i] * norm : 1.0;
      Mat3 M = target_covariances_m2[cr.target_index] +
               R * source_covariances_m2[cr.source_index] * R.transpose();
      M = (0.5 * (M + M.transpose())).eval();
      M.diagonal().array() += floor2;
      omega[i] = information_per_m2(M, floor2);
      if (w == 0.0) continue;
      const Vec3 r = target_points[cr.target_index] - x[i];
      Mat36 J;
      J.leftCols<3>() = -Mat3::Identity();
      J.rightCols<3>() = skew(x[i] - c);
      const Mat36 OJ = omega[i] * J;
      H.noalias() += w * J.transpose() * OJ;
      g.noalias() += w * OJ.transpose() * r;
      chi2 += w * r.dot(omega[i] * r);
    }
  };
  auto singular = [&](const Mat6& A) {
    if (!A.allFinite()) return true;
    const Eigen::SelfAdjointEigenSolver<Mat6> es(A, Eigen::EigenvaluesOnly);
    const double hi = es.eigenvalues().maxCoeff();
    const double lo = es.eigenvalues().minCoeff();
    return !(hi > 0.0) || !(lo > kSingularRatio * hi);
  };

  // The cost at a candidate (Omega at its own rotation): the objective the steps must lower.
  auto cost_at = [&](const Isometry3& Tc) {
    const Mat3 R = Tc.linear();
    double e = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const Correspondence& cr = correspondences[i];
      const double w = weights != nullptr ? (*weights)[i] * norm : 1.0;
      if (w == 0.0) continue;
      Mat3 M = target_covariances_m2[cr.target_index] +
               R * source_covariances_m2[cr.source_index] * R.transpose();
      M = (0.5 * (M + M.transpose())).eval();
      M.diagonal().array() += floor2;
      const Vec3 r = target_points[cr.target_index] - Tc * source_points[cr.source_index];
      e += w * r.dot(information_per_m2(M, floor2) * r);
    }
    return e;
  };

  linearise();
  for (int it = 0; it < options.max_iterations; ++it) {
    if (singular(H)) {
      out.degenerate = true;
      break;
    }
    Vec6d xi = H.ldlt().solve(-g);
    if (!xi.allFinite()) {
      out.degenerate = true;
      break;
    }
    // Far from the minimum (wrong pairs, large rotations) the full Gauss-Newton step can
    // overshoot: halve it until the cost does not rise (at most kMaxHalvings times), else stop.
    bool accepted = false;
    Isometry3 T_next = T;
    for (int h = 0; h <= kMaxHalvings; ++h, xi *= 0.5) {
      // T = Exp_c(xi) T: rotate about c by exp(phi), then translate by rho.
      const Mat3 dR = exp_so3(xi.tail<3>());
      Isometry3 dT = Isometry3::Identity();
      dT.linear() = dR;
      dT.translation() = c - dR * c + xi.head<3>();
      T_next = dT * T;
      T_next.linear() = Eigen::Quaterniond(T_next.linear()).normalized().toRotationMatrix();
      if (!is_finite(T_next)) continue;
      // A step at round-off level needs no check (its cost change is round-off too).
      if (xi.norm() < 1e-12 || cost_at(T_next) <= chi2 * (1.0 + 1e-12)) {
        accepted = true;
        break;
      }
    }
    if (!accepted) break;  // no step lowers the cost: at a minimum to round-off
    T = T_next;
    ++out.iterations;
    linearise();
    if (xi.head<3>().norm() + xi.tail<3>().norm() < options.step_tolerance) break;
  }
  out.T_target_source = T;
  out.chi2 = chi2;
  out.variance_factor = n_used > 2 ? chi2 / static_cast<double>(3 * n_used - 6) : 0.0;
  if (out.degenerate || singular(H)) {
    out.degenerate = true;
    out.covariance = Mat6::Zero();
    return out;
  }
  // Covariance of the perturbation about c, then moved to the origin-based xi of the file
  // comment: rho_0 = rho_c + [c]x phi, phi_0 = phi_c.
  const Mat6 cov_c = H.ldlt().solve(Mat6::Identity());
  Mat6 A = Mat6::Identity();
  A.topRightCorner<3, 3>() = skew(c);
  out.covariance = A * cov_c * A.transpose();
  out.covariance = (0.5 * (out.covariance + out.covariance.transpose())).eval();
  if (!out.covariance.allFinite()) {
    out.degenerate = true;
    out.covariance = Mat6::Zero();
  }
  return out;
}

}  // namespace lmalign
