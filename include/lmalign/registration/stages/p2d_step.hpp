// Estimation on gated pairs: one Gauss-Newton step of the point-to-distribution cost
//   E(T) = sum_i w_i r_i^T Omega_i r_i,  r_i = q_i - T p_i,
// with Omega_i the pair's information from the Mahalanobis gate (both landmarks' covariances, the
// floor and the pose term; GICP's cost, Segal et al. 2009, with SLAM covariances), and w_i each
// pair's weight (a robust kernel of its Mahalanobis distance: the pipeline's kernel stage).
// 6 degrees of freedom, 4 (translation and the rotation about a given up axis only), or 7 (with
// the scale: Sim(3), docs/scale.md).
//
// Parametrisation: a left perturbation about `pivot` (target frame), x -> exp(sigma) Exp(phi)
// (x - pivot) + pivot + rho, xi = (rho [m], phi [rad], sigma = log scale [1]; sigma = 0 when the
// scale is fixed); about the data's centre it is well conditioned even when the map lies
// hundreds of metres from its origin.
#pragma once

#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

/// Which unknowns a step solves: the three bases of the one point-to-distribution solver.
struct P2DBasis {
  enum class Kind {
    k6,  ///< rotation and translation: xi = (rho, phi)
    k4,  ///< translation and the rotation about `up` (unit): x, y, z and yaw
    k7,  ///< rotation, translation and scale: xi = (rho, phi, sigma = log scale), Sim(3)
  };
  Kind kind = Kind::k6;
  Vec3 up = Vec3::UnitZ();
  /// k7: the source landmark covariance of each pair in the target frame (R C_i R^T, m^2; one
  /// per pair, in the pairs' order). A scale change scales it by exp(2 sigma), which changes
  /// each pair's information: the step includes that term, so that it lowers each pair's
  /// Mahalanobis d^2 as the gated score measures it (registration/stages/mahalanobis_gate.hpp)
  /// rather than its residual alone. Null: covariances treated as fixed.
  const std::vector<Mat3>* source_covariances_m2 = nullptr;
  int dof() const { return kind == Kind::k6 ? 6 : (kind == Kind::k4 ? 4 : 7); }
};

/// One solved step.
struct P2DStep {
  bool ok = false;  ///< false: fewer pairs than unknowns, or singular normal equations
  /// (rho [m], phi [rad], sigma [1]) about the pivot; sigma = 0 unless the basis is k7.
  Vec7 xi = Vec7::Zero();
  /// sum w J^T Omega J about the pivot in the basis' unknowns (the rows and columns of the
  /// others are zero: the scale's for k6 and k4, the unused rotations' for k4).
  Mat7 hessian = Mat7::Zero();
  double chi2 = 0.0;  ///< sum w r^T Omega r before the step
  double weight_sum = 0.0;
  int dof = 6;
  /// The pivot's 6x6 block of the Hessian (the rigid unknowns).
  Mat6 hessian_6x6() const { return hessian.topLeftCorner<6, 6>(); }
};

/// The Cauchy weights 1 / (1 + d^2 / scale_d2) of gated pairs (cauchy_weight, robust.hpp): the
/// adaptive default's kernel. scale_d2 > 0.
std::vector<double> cauchy_weights(const std::vector<GatedPair>& pairs, double scale_d2);

/// Solves one Gauss-Newton step on `pairs` (their moved_source_m and information are used; the
/// target points are `target_points[pair.target_index]`) with `weights` (one per pair, >= 0;
/// empty = all 1), in the unknowns of `basis`. The residual of a pair under the perturbation
/// x -> exp(sigma) Exp(phi) (x - pivot) + pivot + rho is r - rho + [x - pivot]x phi -
/// sigma (x - pivot). Never throws for degenerate geometry (ok = false); throws InvalidArgument
/// when the weights or the k7 covariances do not match the pairs.
P2DStep solve_p2d_step(const std::vector<GatedPair>& pairs, const Points3& target_points,
                       const Vec3& pivot_m, const std::vector<double>& weights,
                       const P2DBasis& basis = {});

/// The pose after a step: T <- exp(sigma) Exp(phi) about the pivot, composed on the left of
/// T_target_source. With sigma != 0 the returned scale is exp(sigma), the factor by which the
/// source must be rescaled for the returned rigid transform to apply to it (p_target =
/// T' * (exp(sigma) p)); without, 1 and the rigid step exactly.
Isometry3 apply_step(const Isometry3& T_target_source, const Vec7& xi, const Vec3& pivot_m,
                     double* scale = nullptr);

/// The covariance of the estimate in lmalign's convention (uncertainty.hpp: left perturbation
/// about the target frame's origin) from a step's Hessian about `pivot`, in the step's unknowns:
/// Cov = s^2 A H^-1 A^T with A moving the parameters from the pivot to the origin (rho' = rho +
/// [pivot]x phi - sigma pivot) and s^2 = chi2 / (3 n - dof) (the variance factor, invariant to
/// the scale of the kernel weights; 1 when 3 n <= dof). A k7 step also fills covariance_7x7.
/// `valid` is false when H is singular.
PoseCovariance p2d_covariance(const P2DStep& step, std::size_t num_pairs, const Vec3& pivot_m);

/// The covariance of a 6-DoF point-to-distribution estimate that holds when the landmark errors
/// are correlated (docs/accuracy.md, "Uncertainty of the adaptive default"): a cluster-robust
/// sandwich (Liang and Zeger 1986; the estimate is an M-estimate whose score is
/// g = sum_i w_i J_i^T Omega_i r_i, with w_i, J_i, r_i, Omega_i as in solve_p2d_step) over spatial
/// blocks, never below the model covariance:
///   H = sum_i w_i J_i^T Omega_i J_i,  g_c = sum of g_i over the pairs whose moved source landmark
///   lies in block c (cubes of edge block_m, target frame),
///   B = G / (G - 1) sum_c g_c g_c^T  (G blocks),  S = H^-1 B H^-1,
///   Cov = max(H^-1, S)  (per direction: H^-1 = L L^T, eigen-decompose L^-1 S L^-T and raise its
///   eigenvalues to at least 1),
/// then moved to the target frame's origin as p2d_covariance does. The sandwich sees what the
/// residuals show: landmarks of one block sharing an error (their frames, their trajectory), the
/// robust kernel, landmark covariances that are too small. The model term keeps landmark
/// covariances that are larger than the residuals (conservative maps) as they are. A common error
/// of a whole map (its frame, relative to the other's) leaves no trace in the residuals and is
/// not in it. sigma_m = sqrt(chi2 / (3n - 6)) as in p2d_covariance.
/// `pairs` and `weights` as solve_p2d_step (their moved_source_m at the estimate), `block_m` > 0
/// and finite; `basis` k6 (the rotation and translation) or k7 (with the scale: the 7x7 in
/// covariance_7x7). valid = false when H is singular or n < 3. Never throws for degenerate
/// geometry; throws InvalidArgument for block_m <= 0 or non-finite, weights that do not match the
/// pairs, or a k4 basis.
PoseCovariance p2d_cluster_covariance(const std::vector<GatedPair>& pairs,
                                      const Points3& target_points, const Vec3& pivot_m,
                                      const std::vector<double>& weights, double block_m,
                                      const P2DBasis& basis = {});

}  // namespace lmalign
