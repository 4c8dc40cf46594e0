// Estimation with scale (Sim(3), core/similarity.hpp): the seventh degree of freedom for maps
// without a common metric scale.
//
// - Umeyama's closed form with scale (Umeyama 1991, "Least-squares estimation of transformation
//   parameters between two point patterns", eqs. 40-42; as COLMAP's model_aligner estimates its
//   Sim3d): the option of the paper's strategies (point pairs).
// - One Gauss-Newton step of the point-to-distribution cost in 7 DoF: the adaptive default's
//   (point-to-distribution pairs, stages/p2d_step.hpp), its normal equations and its 7x7
//   covariance.
//
// Parametrisation of a step: a left perturbation about `pivot` (target frame),
//   x -> exp(sigma) Exp(phi) (x - pivot) + pivot + rho,  xi = (rho [target units], phi [rad],
//   sigma = log scale [1]).
// Frames: p_target = scale * R * p_source + t.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/core/types.hpp"

namespace lmalign {

using Vec7 = Eigen::Matrix<double, 7, 1>;
using Mat7 = Eigen::Matrix<double, 7, 7>;

/// Whether an alignment estimates the scale. kAuto: free when either map has no metric scale
/// (its header says arbitrary or unknown), fixed otherwise.
enum class ScaleMode { kAuto, kFree, kFixed };
inline constexpr EnumName<ScaleMode> kScaleModeNames[] = {
    {ScaleMode::kAuto, "auto"}, {ScaleMode::kFree, "free"}, {ScaleMode::kFixed, "fixed"}};
/// "auto", "free", "fixed".
std::string to_string(ScaleMode mode);
/// The mode of a name above; throws InvalidArgument "unknown scale mode 'NAME' (known: auto,
/// free, fixed)".
ScaleMode parse_scale_mode(const std::string& name);
/// kFree or kFixed: auto resolved from whether each map's lengths are metres.
ScaleMode resolve_scale_mode(ScaleMode mode, bool source_metric, bool target_metric);

/// Umeyama's weighted least-squares similarity (1991, eqs. 40-42) mapping `source` onto `target`
/// pair by pair: c = trace(D S) / sigma_s^2 (eq. 42), R = U S V^T (eq. 40, S = diag(1, 1, -1)
/// when det(U) det(V) < 0), t = mu_t - c R mu_s (eq. 41). `weights`: one per pair (>= 0, sum > 0)
/// or null for all 1. nullopt when there are fewer than 3 pairs, the source points coincide
/// (sigma_s^2 = 0) or the result is not finite. Throws InvalidArgument when the sizes differ.
std::optional<Similarity3> umeyama_similarity(const Points3& source, const Points3& target,
                                              const std::vector<double>* weights = nullptr);

/// The normal equations of the 7-DoF cost sum w_i r_i^T Omega_i r_i, r_i = q_i - x_i (x_i the
/// moved source landmark, q_i its target landmark), and the step that solves them.
struct SimilarityStep {
  bool ok = false;         ///< false: fewer than 3 pairs, or singular normal equations
  Vec7 xi = Vec7::Zero();  ///< (rho, phi, sigma) about the pivot
  Mat7 hessian = Mat7::Zero();
  double chi2 = 0.0;  ///< sum w r^T Omega r before the step
  std::size_t num_pairs = 0;
};

/// One Gauss-Newton step. `information`: one 3x3 per pair (null: identity, the point-to-point
/// cost); `weights`: one per pair or empty for all 1. Throws InvalidArgument when sizes differ.
SimilarityStep solve_similarity_step(const Points3& moved, const Points3& targets,
                                     const std::vector<Mat3>* information,
                                     const std::vector<double>& weights, const Vec3& pivot);

/// The similarity x -> exp(sigma) Exp(phi) (x - pivot) + pivot + rho of a step.
Similarity3 similarity_increment(const Vec7& xi, const Vec3& pivot);

/// The 7x7 covariance of the estimate from a step's normal equations, as p2d_covariance does in
/// 6 DoF: s^2 A H^-1 A^T with s^2 = chi2 / (3 n - 7) and A moving the parameters from the pivot
/// to the target origin (rho' = rho + [pivot]x phi - sigma pivot). Order (rho [target units],
/// phi [rad], sigma = log scale). nullopt when H is singular or n < 3.
std::optional<Mat7> similarity_covariance(const SimilarityStep& step, const Vec3& pivot);

/// The scale that brings the source's typical landmark spacing (median nearest-neighbour
/// distance) to the target's: target_spacing / source_spacing, clamped to [1/10, 10]. Both > 0.
double initial_scale_from_spacing(double source_spacing, double target_spacing);

}  // namespace lmalign
