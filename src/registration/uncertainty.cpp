#include "lmalign/registration/uncertainty.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/symmetric_eigen.hpp"

namespace lmalign {

namespace {

constexpr double kRadToDeg = 57.29577951308232;

}  // namespace

double PoseCovariance::translation_sd_m() const {
  if (!valid) return std::numeric_limits<double>::infinity();
  return std::sqrt(
      std::max(0.0, Eigen::SelfAdjointEigenSolver<Mat3>(covariance.topLeftCorner<3, 3>())
                        .eigenvalues()
                        .maxCoeff()));
}

double PoseCovariance::rotation_sd_deg() const {
  if (!valid) return std::numeric_limits<double>::infinity();
  return kRadToDeg * std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Mat3>(
                                                 covariance.bottomRightCorner<3, 3>())
                                                 .eigenvalues()
                                                 .maxCoeff()));
}

namespace {

// point_to_point_covariance in N unknowns: 6 (rho, phi) or 7 (with sigma = log scale, whose
// column of the Jacobian of x -> exp(sigma) x is x).
template <int N>
PoseCovariance point_to_point_n(const Points3& moved_source, const Points3& target_points,
                                const Correspondences& correspondences,
                                const std::vector<double>* weights) {
  using MatN = Eigen::Matrix<double, N, N>;
  PoseCovariance out;
  const std::size_t n = correspondences.size();
  out.num_correspondences = n;
  if (weights != nullptr && weights->size() != n) {
    throw InvalidArgument("point_to_point_covariance: " + std::to_string(weights->size()) +
                          " weights for " + std::to_string(n) + " correspondences");
  }
  double norm = 1.0;  // weights normalised to mean 1
  if (weights != nullptr) {
    double wsum = 0.0;
    for (double w : *weights) wsum += w;
    if (!(wsum > 0.0)) return out;
    norm = static_cast<double>(n) / wsum;
  }
  MatN H = MatN::Zero();
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Correspondence& c = correspondences[i];
    const double w = weights != nullptr ? (*weights)[i] * norm : 1.0;
    if (c.source_index >= moved_source.size() || c.target_index >= target_points.size()) {
      throw InvalidArgument("point_to_point_covariance: correspondence index out of range");
    }
    const Vec3& x = moved_source[c.source_index];
    const Vec3 r = target_points[c.target_index] - x;
    Eigen::Matrix<double, 3, N> J;
    J.template leftCols<3>() = Mat3::Identity();
    J.template block<3, 3>(0, 3) = -skew(x);
    if constexpr (N == 7) J.col(6) = x;
    H.noalias() += w * J.transpose() * J;
    sum_sq += w * r.squaredNorm();
  }
  if (n < 3) return out;
  const SymmetricEigen<N> eig = symmetric_eigen(H);
  const double lmax = eig.values.maxCoeff();
  if (!(eig.values.minCoeff() > 1e-12 * lmax)) return out;  // singular: a line
  const double dof = 3.0 * static_cast<double>(n) - static_cast<double>(N);
  const double sigma2 = sum_sq / dof;
  out.sigma_m = std::sqrt(sigma2);
  const MatN cov =
      sigma2 * (eig.vectors * eig.values.cwiseInverse().asDiagonal() * eig.vectors.transpose());
  const MatN symmetric = 0.5 * (cov + cov.transpose());  // exactly symmetric
  if constexpr (N == 7) {
    out.has_scale = true;
    out.covariance_7x7 = symmetric;
    out.covariance = symmetric.template topLeftCorner<6, 6>();
  } else {
    out.covariance = symmetric;
  }
  out.valid = symmetric.allFinite();
  if (!out.valid) {
    out.covariance.setZero();
    out.covariance_7x7.setZero();
  }
  return out;
}

}  // namespace

PoseCovariance point_to_point_covariance(const Points3& moved_source, const Points3& target_points,
                                         const Correspondences& correspondences,
                                         const std::vector<double>* weights, bool with_scale) {
  return with_scale ? point_to_point_n<7>(moved_source, target_points, correspondences, weights)
                    : point_to_point_n<6>(moved_source, target_points, correspondences, weights);
}

Vec7 similarity_error_twist(const Isometry3& T_est, double scale_est, const Isometry3& T_true) {
  // S_est S_true^-1 (x) = s R_e R_t^T (x - t_t) + t_e: sigma = log s, phi = log(R_e R_t^T),
  // rho = t_e - s R_e R_t^T t_t.
  const Mat3 dR = T_est.linear() * T_true.linear().transpose();
  const Eigen::AngleAxisd aa(dR);
  Vec7 xi;
  xi.head<3>() = T_est.translation() - scale_est * (dR * T_true.translation());
  xi.segment<3>(3) = aa.axis() * aa.angle();
  xi(6) = std::log(scale_est);
  return xi;
}

Vec6 pose_error_twist(const Isometry3& T_est, const Isometry3& T_true) {
  const Isometry3 E = T_est * T_true.inverse();
  const Eigen::AngleAxisd aa(E.rotation());
  Vec6 xi;
  xi.head<3>() = E.translation();
  xi.tail<3>() = aa.axis() * aa.angle();
  return xi;
}

namespace {
template <int N>
Eigen::Matrix<double, N, N> covariance_max_n(const Eigen::Matrix<double, N, N>& floor,
                                             const Eigen::Matrix<double, N, N>& other) {
  using M = Eigen::Matrix<double, N, N>;
  const Eigen::LLT<M> llt(floor);
  if (llt.info() != Eigen::Success) return floor;
  const M L = llt.matrixL();
  const M L_inv = L.inverse();
  M K = L_inv * other * L_inv.transpose();
  K = (0.5 * (K + K.transpose())).eval();
  const SymmetricEigen<N> eig = symmetric_eigen(K);
  const Eigen::Matrix<double, N, 1> d = eig.values.cwiseMax(1.0);
  const M raised = L * eig.vectors * d.asDiagonal() * eig.vectors.transpose() * L.transpose();
  return raised.allFinite() ? raised : floor;
}
}  // namespace

Mat6 covariance_max(const Mat6& floor, const Mat6& other) { return covariance_max_n<6>(floor, other); }

Mat7 covariance_max(const Mat7& floor, const Mat7& other) { return covariance_max_n<7>(floor, other); }

double nees(const Vec6& error, const PoseCovariance& covariance) {
  if (!covariance.valid) return std::numeric_limits<double>::infinity();
  return error.dot(covariance.covariance.ldlt().solve(error));
}

bool TrustOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (!(inlier_distance_m > 0.0) || !std::isfinite(inlier_distance_m)) {
    return fail("inlier_distance_m must be > 0 and finite, got " +
                message_number(inlier_distance_m));
  }
  if (!(overlap_distance_m >= inlier_distance_m) || !std::isfinite(overlap_distance_m)) {
    return fail("overlap_distance_m must be finite and >= inlier_distance_m, got " +
                message_number(overlap_distance_m));
  }
  if (!(min_inlier_ratio >= 0.0 && min_inlier_ratio <= 1.0)) {
    return fail("min_inlier_ratio must be in [0, 1], got " + message_number(min_inlier_ratio));
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) {
    return fail("min_inlier_fraction must be in [0, 1], got " +
                message_number(min_inlier_fraction));
  }
  if (!(max_translation_sd_m > 0.0)) {
    return fail("max_translation_sd_m must be > 0, got " + message_number(max_translation_sd_m));
  }
  if (!(max_rotation_sd_deg > 0.0)) {
    return fail("max_rotation_sd_deg must be > 0, got " + message_number(max_rotation_sd_deg));
  }
  return true;
}

TrustVerdict judge_alignment(const Points3& source_points, const KdTree& target,
                             const Isometry3& T_target_source, const TrustOptions& options,
                             PoseCovariance* inlier_covariance) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("trust options: " + why);
  if (source_points.empty()) throw InvalidArgument("judge_alignment: the source has no points");
  const std::size_t n = source_points.size();
  Points3 moved(n);
  std::vector<PointIndex> nn(n, 0);
  std::vector<double> d2(n, std::numeric_limits<double>::infinity());
  FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    error.capture([&] {
      const auto s = static_cast<std::size_t>(i);
      moved[s] = T_target_source * source_points[s];
      if (!target.nearest(moved[s], &nn[s], &d2[s])) {
        d2[s] = std::numeric_limits<double>::infinity();
      }
    });
  }
  error.rethrow();
  const double in2 = options.inlier_distance_m * options.inlier_distance_m;
  const double ov2 = options.overlap_distance_m * options.overlap_distance_m;
  Correspondences inliers;
  std::size_t overlap = 0;
  for (std::size_t s = 0; s < n; ++s) {
    if (d2[s] <= ov2) ++overlap;
    if (d2[s] <= in2) inliers.push_back({static_cast<PointIndex>(s), nn[s], d2[s]});
  }
  const PoseCovariance cov = point_to_point_covariance(moved, target.points(), inliers);
  if (inlier_covariance != nullptr) *inlier_covariance = cov;

  TrustVerdict v;
  v.inlier_fraction = static_cast<double>(inliers.size()) / static_cast<double>(n);
  v.overlap_fraction = static_cast<double>(overlap) / static_cast<double>(n);
  v.translation_sd_m = cov.translation_sd_m();
  v.rotation_sd_deg = cov.rotation_sd_deg();
  const double ratio = overlap > 0 ? static_cast<double>(inliers.size()) / overlap : 0.0;
  if (!(v.inlier_fraction >= options.min_inlier_fraction)) {
    v.reason = "inlier fraction " + message_number(v.inlier_fraction) + " below " +
               message_number(options.min_inlier_fraction) + " (too little overlap)";
  } else if (!(ratio >= options.min_inlier_ratio)) {
    v.reason = "inlier ratio " + message_number(ratio) + " below " +
               message_number(options.min_inlier_ratio) +
               " (landmarks in the overlap do not coincide)";
  } else if (!cov.valid) {
    v.reason = "the inliers do not determine the transform (degenerate)";
  } else if (!(v.translation_sd_m <= options.max_translation_sd_m)) {
    v.reason = "translation sd " + message_number(v.translation_sd_m) + " m above " +
               message_number(options.max_translation_sd_m);
  } else if (!(v.rotation_sd_deg <= options.max_rotation_sd_deg)) {
    v.reason = "rotation sd " + message_number(v.rotation_sd_deg) + " deg above " +
               message_number(options.max_rotation_sd_deg);
  } else {
    v.trustworthy = true;
    v.reason = "ok";
  }
  return v;
}

}  // namespace lmalign
