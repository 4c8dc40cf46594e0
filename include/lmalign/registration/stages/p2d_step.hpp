// Estimation on gated pairs: one Gauss-Newton step of the point-to-distribution cost
//   E(T) = sum_i w_i r_i^T Omega_i r_i,  r_i = q_i - T p_i,
// with Omega_i the pair's information from the Mahalanobis gate (both landmarks' covariances, the
// floor and the pose term; GICP's cost, Segal et al. 2009, with SLAM covariances), and w_i each
// pair's weight (a robust kernel of its Mahalanobis distance: the pipeline's kernel stage).
// 6 degrees of freedom, or 4 (translation and the rotation about a given up axis only).
//
// Parametrisation: a left perturbation about `pivot` (target frame), x -> Exp(phi)(x - pivot) +
// pivot + rho, xi = (rho [m], phi [rad]); about the data's centre it is well conditioned even
// when the map lies hundreds of metres from its origin.
#pragma once

#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

/// One solved step.
struct P2DStep {
  bool ok = false;              ///< false: fewer pairs than unknowns, or singular normal equations
  Vec6 xi = Vec6::Zero();       ///< (rho [m], phi [rad]) about the pivot
  Mat6 hessian = Mat6::Zero();  ///< sum w J^T Omega J about the pivot (the 4-DoF rows/cols of
                                ///< the unused rotations are zero)
  double chi2 = 0.0;            ///< sum w r^T Omega r before the step
  double weight_sum = 0.0;
};

/// The Cauchy weights 1 / (1 + d^2 / scale_d2) of gated pairs (cauchy_weight, robust.hpp): the
/// adaptive default's kernel. scale_d2 > 0.
std::vector<double> cauchy_weights(const std::vector<GatedPair>& pairs, double scale_d2);

/// Solves one step on `pairs` (their moved_source_m and information are used; the target points
/// are `target_points[pair.target_index]`) with `weights` (one per pair, >= 0; empty = all 1).
/// `up`: nullptr for 6 DoF, else the unit up axis of a 4-DoF step. Never throws for degenerate
/// geometry (ok = false); throws InvalidArgument when the weights do not match the pairs.
P2DStep solve_p2d_step(const std::vector<GatedPair>& pairs, const Points3& target_points,
                       const Vec3& pivot_m, const std::vector<double>& weights,
                       const Vec3* up = nullptr);

/// T <- Exp(xi) about pivot, composed on the left of T_target_source.
Isometry3 apply_step(const Isometry3& T_target_source, const Vec6& xi, const Vec3& pivot_m);

/// The 6x6 covariance of the estimate in lmalign's convention (uncertainty.hpp: left
/// perturbation about the target frame's origin) from a step's Hessian about `pivot`:
/// Cov = s^2 A H^-1 A^T with A = [[I, [pivot]x], [0, I]] and s^2 = chi2 / (3 n - 6) (the
/// variance factor, invariant to the scale of the kernel weights; 1 when n <= 2). `valid` is false
/// when H is singular.
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
/// and finite. valid = false when H is singular or n < 3. Never throws for degenerate geometry;
/// throws InvalidArgument for block_m <= 0 or non-finite, or weights that do not match the pairs.
PoseCovariance p2d_cluster_covariance(const std::vector<GatedPair>& pairs,
                                      const Points3& target_points, const Vec3& pivot_m,
                                      const std::vector<double>& weights, double block_m);

}  // namespace lmalign
