// The pose graph of a merge (docs/merge.md, "Pose graph"), solved with Ceres.
//
// Unknowns: T_world_map of every map (SE(3): translation + unit quaternion, with a manifold whose
// tangent is uncertainty.hpp's left perturbation in the world frame, T = Exp(xi) T_hat with
// Exp(xi) = [Exp(phi), rho]). Factors:
//   edge  (i -> j, measured T_j_i, covariance C in frame j):
//         xi = Log-ish(T_wj^-1 T_wi * T_ji_meas^-1) = (translation, rotation vector), r = L^-1 xi
//         with C * s = L L^T (s: the edge covariance scale, below);
//   prior (map i, T_prior, C_prior): xi of T_wi * T_prior^-1, r = L^-1 xi.
// Robust: the first solve uses a Cauchy loss on the squared whitened residual (scale
// `cauchy_scale`), so one false edge cannot bend the graph; edges whose chi^2 = |r|^2 then
// exceeds the chi^2(6) quantile `reject_quantile` are rejected, and the graph is solved again
// without them and without the loss (repeated until nothing more is rejected, at most
// max_rounds). The final chi^2 and the marginal covariances (ceres::Covariance) come from that
// last, plain least-squares solve.
// Gauge: each connected component (of the kept edges) with at least one prior is held by its
// priors; one without is fixed at its first map (lowest index) = identity, covariance zero.
// Components are never forced together: each is reported in its own frame.
//
// Maps without metric scale (Sim(3), `scale_free`): each such map also has a log scale
// lambda_i, S_world_map = (exp(lambda_i), T_world_map): p_world = exp(lambda_i) R_i p_map + t_i.
// The edge factor becomes 7-dimensional: xi = (rho, phi, sigma) of S_j_i_pred * S_j_i_meas^-1
// with S_j_i_pred = S_wj^-1 S_wi, rho = t_pred - exp(sigma) R_err t_meas (target units),
// sigma = lambda_i - lambda_j - log s_meas, whitened by the edge's 7x7 covariance (its
// Edge::covariance 6x6 block, its log-scale variance and their correlations from
// Edge::covariance_7x7; without one, the 6x6 and the scale sd, uncorrelated). The scale is held
// where it is known: lambda = 0 for a map with metric scale, log MapPrior::scale for a map with
// a prior, and, in a component with neither, lambda = 0 at its gauge map. The cycle check and the
// rejection use chi^2(7) then. Without any map of free scale the graph is the rigid one above,
// bit for bit.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/similarity.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/manifest.hpp"

namespace lmalign {

struct PoseGraphOptions {
  /// Cauchy loss scale on the whitened residual norm (rho(s) = a^2 log(1 + s / a^2) with
  /// s = |r|^2, a = cauchy_scale), > 0.
  double cauchy_scale = 3.0;
  /// An edge is rejected when its chi^2 exceeds the chi^2(6) quantile of this probability,
  /// in (0.5, 1) (0.999: 22.46).
  double reject_quantile = 0.999;
  /// Edge covariance scale s (> 0), or 0: estimated from the graph's redundancy when there is
  /// some (docs/merge.md): s = max(1, median edge chi^2 / (5.348 * redundancy)), redundancy =
  /// (edges - maps + components) / edges, over the edges of the robust solve. Untrusted (not
  /// calibrated) covariances are then not over-confident, and a false edge does not count.
  double edge_covariance_scale = 0.0;
  /// Covariance floor (documented guard): each edge covariance's eigenvalues are raised to at
  /// least floor_translation_m^2 (translation block) and floor_rotation_deg^2 (rotation block,
  /// in rad^2) before whitening. > 0.
  double floor_translation_m = 1e-3;
  double floor_rotation_deg = 0.01;
  /// Floor of an edge's log-scale standard deviation (relative scale sd), > 0: the model
  /// covariance of a 7-DoF step does not see errors the whole map shares (docs/scale.md).
  double floor_log_scale = 1e-3;
  /// Cycle check before the solve (docs/merge.md, "Pose graph"): an edge between two maps with
  /// priors is rejected when it disagrees with their relative prior; then the edges are taken
  /// by decreasing inliers, Kruskal-fashion, and an edge that closes a cycle is rejected when it
  /// disagrees with the path of stronger edges between its maps. Disagrees: beyond the chi^2(6)
  /// `reject_quantile` under the sum of the two covariances. In an inconsistent cycle the
  /// weakest edge goes, where the robust solve alone may keep any two of three.
  bool check_cycles = true;
  int max_rounds = 4;        ///< >= 1
  int max_iterations = 100;  ///< Ceres iterations per solve, >= 1
  bool compute_covariances = true;
  bool is_valid(std::string* why = nullptr) const;
};

/// One map's result.
struct MapPose {
  Isometry3 T_world_map = Isometry3::Identity();
  /// Marginal covariance (uncertainty.hpp's convention, world frame); zero for a gauge map.
  Mat6 covariance = Mat6::Zero();
  bool covariance_valid = false;
  std::size_t component = 0;  ///< 0-based, components ordered by their lowest map index
  bool is_gauge = false;      ///< fixed at identity (a component without priors)
  /// World units per map unit: p_world = scale * R * p_map + t with (R, t) = T_world_map.
  /// Exactly 1 for a map with metric scale.
  double scale = 1.0;
  /// Its standard deviation (world units per map unit); 0 when held (metric, prior or gauge).
  double scale_sd = 0.0;
  bool scale_free = false;  ///< estimated (a map without metric scale, not held)
  /// S_world_map = [scale R, t; 0 0 0 1].
  Similarity3 similarity() const { return Similarity3{scale, T_world_map}; }
};

/// One edge's fate in the graph (same order as the edges given).
struct EdgeReport {
  bool used = false;        ///< trusted and with a usable covariance: entered the graph
  bool rejected = false;    ///< used, then rejected after optimisation
  double chi2 = 0.0;        ///< whitened chi^2 at the final poses (with the scale), 0 if unused
  std::string skip_reason;  ///< why not used ("untrusted: ...", "invalid covariance")
  /// Why rejected, when by the cycle check (empty: by the chi^2 after optimisation, or kept).
  std::string reject_reason;
};

struct MergeResult {
  std::vector<MapPose> maps;
  std::vector<EdgeReport> edges;
  std::size_t num_components = 0;
  double final_chi2 = 0.0;  ///< sum over the kept edges and the priors
  double edge_covariance_scale = 1.0;
  int rounds = 0;
  bool converged = false;
};

/// Solves the graph of `num_maps` maps with `priors` (size num_maps, empty = none) and `edges`.
/// `scale_free[i]`: map i has no metric scale, so its scale is estimated (see the file comment);
/// empty: every map is metric (the rigid graph). Throws InvalidArgument on invalid options,
/// sizes that do not match, an edge naming a map out of range, or a prior whose scale is not
/// finite and > 0.
MergeResult solve_pose_graph(std::size_t num_maps,
                             const std::vector<std::optional<MapPrior>>& priors,
                             const std::vector<Edge>& edges, const PoseGraphOptions& options = {},
                             const std::vector<bool>& scale_free = {});

/// Quantile of the chi^2 distribution with `dof` degrees of freedom (Wilson-Hilferty
/// approximation, within 1% for dof >= 3 and p in [0.9, 0.9999]).
double chi2_quantile(double p, int dof);

}  // namespace lmalign
