#include "lmalign/registration/estimation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <omp.h>

#include <Eigen/SVD>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"

namespace lmalign {

namespace {

// Throws InvalidArgument unless there are n weights (or none), each finite and >= 0.
void check_weights(const std::vector<double>* weights, std::size_t n) {
  if (n == 0) throw InvalidArgument("estimate_rigid_transform: no correspondences");
  if (weights == nullptr) return;
  if (weights->size() != n) {
    throw InvalidArgument("estimate_rigid_transform: " + std::to_string(weights->size()) +
                          " weights for " + std::to_string(n) + " correspondences");
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite((*weights)[i]) || (*weights)[i] < 0.0) {
      throw InvalidArgument("estimate_rigid_transform: weight " + std::to_string(i) + " is " +
                            std::to_string((*weights)[i]) + ", expected finite and >= 0");
    }
  }
}

// The rotation of Umeyama's closed form from the cross-covariance H = sum w (s - mu_s)(t -
// mu_t)^T: R = V diag(1, 1, d) U^T maximises trace(R H) over rotations, d = det(V U^T) (-1 or
// 1). Rank <= 1 (identical or collinear points on either side): every rotation taking u_0 onto
// v_0 (rank 1), or any rotation at all (rank 0), is a minimiser, and the SVD's choice among them
// is arbitrary; the smallest one is taken instead (d = 1), so the result is deterministic and
// no spurious spin about the line is introduced.
struct UmeyamaRotation {
  Mat3 R = Mat3::Identity();
  Vec3 sigma = Vec3::Zero();  ///< H's singular values, descending, >= 0
  bool degenerate = false;
  double d = 1.0;
};

UmeyamaRotation umeyama_rotation(const Mat3& H) {
  Eigen::JacobiSVD<Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3& U = svd.matrixU();
  const Mat3& V = svd.matrixV();
  const Vec3 sigma = svd.singularValues();  // descending, >= 0
  const bool degenerate =
      !(sigma(0) > 0.0) || sigma(1) <= EstimationReport::kDegenerateRatio * sigma(0);
  Mat3 R;
  double d = 1.0;
  if (!degenerate) {
    if ((V * U.transpose()).determinant() < 0.0) d = -1.0;
    Mat3 D = Mat3::Identity();
    D(2, 2) = d;
    R = V * D * U.transpose();
  } else if (sigma(0) > 0.0) {
    // Normalised: near-opposite vectors leave FromTwoVectors' quaternion off unit norm by up to
    // 1e-4 (then R would not be a rotation; found by fuzz_map_reader).
    R = Quat::FromTwoVectors(U.col(0), V.col(0)).normalized().toRotationMatrix();
  } else {
    R = Mat3::Identity();
  }
  return {R, sigma, degenerate, d};
}

// The one closed form (Umeyama 1991): rigid when kScale is false (eqs. 40-41 with c = 1), with
// the scale of eq. 42 when true (*scale receives it).
template <bool kScale>
Isometry3 umeyama(const Points3& source_points, const Points3& target_points,
                  const Correspondences& correspondences, const std::vector<double>* weights,
                  EstimationReport* report, double* scale) {
  const std::size_t n = correspondences.size();
  check_weights(weights, n);
  auto w = [&](std::size_t i) { return weights == nullptr ? 1.0 : (*weights)[i]; };

  // Sums over at most kMaxBlocks blocks of at least kMinBlock correspondences (their sizes depend
  // on n only), combined in block order: the same result for any thread count. The blocks run
  // in parallel when not already inside a parallel region; no allocation.
  constexpr std::size_t kMaxBlocks = 16;
  constexpr std::size_t kMinBlock = 512;
  // Waking the thread pool costs tens of microseconds (OMP_WAIT_POLICY=passive): only worth it
  // for large sets (measured on the real pair: 3,050 correspondences lost 0.07 ms per iteration).
  constexpr std::size_t kParallelMin = 50000;
  const std::size_t block = std::max(kMinBlock, (n + kMaxBlocks - 1) / kMaxBlocks);
  const std::size_t blocks = (n + block - 1) / block;
  struct Partial {
    double w_sum = 0.0;
    Vec3 s = Vec3::Zero(), t = Vec3::Zero();
    Mat3 H = Mat3::Zero();
    double var_s = 0.0;  // sum w |s - mu_s|^2 (kScale)
  };
  std::array<Partial, kMaxBlocks> partial;
  const bool parallel = n >= kParallelMin && blocks > 1 && !omp_in_parallel();

  // Pass 1: weighted centroids. (No body here throws; FirstException keeps it so if one ever
  // does: an exception may not leave an OpenMP region.)
  FirstException error;
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(blocks); ++b) {
    error.capture([&] {
      // Local accumulators (kept in registers), stored once per block.
      double ws = 0.0;
      Vec3 ss = Vec3::Zero(), ts = Vec3::Zero();
      const std::size_t end = std::min(n, (static_cast<std::size_t>(b) + 1) * block);
      for (std::size_t i = static_cast<std::size_t>(b) * block; i < end; ++i) {
        const Correspondence& c = correspondences[i];
        const double wi = w(i);
        ws += wi;
        ss += wi * source_points[c.source_index];
        ts += wi * target_points[c.target_index];
      }
      Partial& p = partial[static_cast<std::size_t>(b)];
      p.w_sum = ws;
      p.s = ss;
      p.t = ts;
    });
  }
  error.rethrow();
  double w_sum = 0.0;
  Vec3 mu_s = Vec3::Zero();
  Vec3 mu_t = Vec3::Zero();
  for (std::size_t b = 0; b < blocks; ++b) {
    const Partial& p = partial[b];
    w_sum += p.w_sum;
    mu_s += p.s;
    mu_t += p.t;
  }
  if (!(w_sum > 0.0)) {
    throw InvalidArgument("estimate_rigid_transform: the weights sum to " + std::to_string(w_sum) +
                          ", expected > 0");
  }
  mu_s /= w_sum;
  mu_t /= w_sum;

  // Pass 2: cross-covariance of the demeaned points, H = sum w (s - mu_s)(t - mu_t)^T.
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(blocks); ++b) {
    error.capture([&] {
      Mat3 Hb = Mat3::Zero();
      double vb = 0.0;
      const std::size_t end = std::min(n, (static_cast<std::size_t>(b) + 1) * block);
      for (std::size_t i = static_cast<std::size_t>(b) * block; i < end; ++i) {
        const Correspondence& c = correspondences[i];
        Hb.noalias() += w(i) * (source_points[c.source_index] - mu_s) *
                        (target_points[c.target_index] - mu_t).transpose();
        if constexpr (kScale) vb += w(i) * (source_points[c.source_index] - mu_s).squaredNorm();
      }
      partial[static_cast<std::size_t>(b)].H = Hb;
      partial[static_cast<std::size_t>(b)].var_s = vb;
    });
  }
  error.rethrow();
  Mat3 H = Mat3::Zero();
  for (std::size_t b = 0; b < blocks; ++b) H += partial[b].H;

  if (!H.allFinite() || !mu_s.allFinite() || !mu_t.allFinite()) {
    throw InvalidArgument(
        "estimate_rigid_transform: the cross-covariance overflows (coordinates too large)");
  }

  const UmeyamaRotation rot = umeyama_rotation(H);
  const Mat3& R = rot.R;
  const Vec3& sigma = rot.sigma;
  if (report != nullptr) {
    report->singular_values = sigma;
    report->degenerate = rot.degenerate;
  }

  Isometry3 T = Isometry3::Identity();
  T.linear() = R;
  if constexpr (kScale) {
    // Eq. 42: c = trace(D Sigma) / sigma_s^2 (the weights' sum cancels); undetermined (1) when
    // the source points coincide.
    double var_s = 0.0;
    for (std::size_t b = 0; b < blocks; ++b) var_s += partial[b].var_s;
    const double c = var_s > 0.0 ? (sigma(0) + sigma(1) + rot.d * sigma(2)) / var_s : 1.0;
    *scale = c > 0.0 && std::isfinite(c) ? c : 1.0;
    T.translation() = mu_t - *scale * (R * mu_s);
  } else {
    T.translation() = mu_t - R * mu_s;
  }
  if (!T.matrix().allFinite()) {
    throw InvalidArgument(
        "estimate_rigid_transform: the estimate is not finite (coordinates too "
        "large)");
  }
  return T;
}

}  // namespace

Isometry3 estimate_rigid_transform(const Points3& source_points, const Points3& target_points,
                                   const Correspondences& correspondences,
                                   const std::vector<double>* weights, EstimationReport* report) {
  return umeyama<false>(source_points, target_points, correspondences, weights, report, nullptr);
}

Similarity3 estimate_similarity_transform(const Points3& source_points,
                                          const Points3& target_points,
                                          const Correspondences& correspondences,
                                          const std::vector<double>* weights,
                                          EstimationReport* report) {
  Similarity3 S;
  S.rigid = umeyama<true>(source_points, target_points, correspondences, weights, report, &S.scale);
  return S;
}

}  // namespace lmalign
