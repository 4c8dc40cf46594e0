// One entry point for every named strategy (the CLI's `align`, the experiment runner and the
// Python bindings all call it, so that they agree bit for bit): the paper's four run through
// align(), lmalign's robust presets through align_robust(), `adaptive` through align_adaptive().
// Each result carries a trust verdict: the adaptive pipeline's own (covariance-gated inliers,
// ambiguity), or judge_alignment() (uncertainty.hpp) for the others.
//
// Frames: T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/adaptive.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

/// The source as every strategy may need it: positions (metres), covariances (m^2; may be empty
/// unless a point-to-distribution preset is asked for) and the up axis (adaptive only), all in
/// the source frame.
struct StrategySource {
  Points3 positions;
  std::vector<Mat3> covariances_m2;
  std::optional<Vec3> up;
};

/// What to run.
struct StrategyRequest {
  PaperStrategy strategy = kRecommendedStrategy;
  /// Neighbourhood size of the weighted-kNN selections, [1, 4096].
  int k = 5;
  /// The paper's strategies: iteration budget and maximum correspondence distance (metres;
  /// +inf = unlimited), as in the paper. lmalign's robust presets: when either is set, the
  /// preset is capped by with_limits(). The adaptive pipeline: max_iterations caps each of its
  /// refinements; max_distance_m does not apply (its gate follows the covariances).
  std::optional<int> max_iterations;
  std::optional<double> max_distance_m;
  /// The start (every strategy); for `adaptive`, a hypothesis of its search, or with `prior`
  /// the centre of the bounded search.
  std::optional<Isometry3> initial_guess;
  /// `adaptive` only: bounds the search around the initial guess (identity if none).
  std::optional<PriorSigma> prior;
  /// The paper's strategies: per-iteration history (RegistrationOptions::record_history and
  /// history_scores).
  bool record_history = false;
};

/// What came out.
struct StrategyOutcome {
  RegistrationResult result;
  bool trustworthy = false;
  std::string trust_reason;
  /// The estimate's 6x6 covariance (uncertainty.hpp's convention): the adaptive pipeline's
  /// point-to-distribution covariance, else judge_alignment's point-to-point one on its inliers.
  PoseCovariance covariance;
  /// judge_alignment's verdict (strategies other than adaptive).
  std::optional<TrustVerdict> verdict;
  /// The adaptive pipeline's full result (adaptive only).
  std::optional<AdaptiveResult> adaptive;
  /// Landmarks of each side left out of the alignment for being beyond the supported range
  /// (core/supported_range.hpp); when any were, trust_reason ends with "; " and
  /// left_out_message() (e.g. "ok; 1 source landmark beyond the supported range (|coordinate| >
  /// 1e+15 m) left out"), and the verdict is that of the alignment of the others.
  std::size_t source_left_out = 0;
  std::size_t target_left_out = 0;
};

/// Runs one strategy: the one entry of every alignment (the CLI's `align`, the Python package,
/// the merge's edges, the experiment runner's own strategies). Applies the supported range
/// (core/supported_range.hpp): landmarks of either side beyond it are left out and counted
/// (StrategyOutcome::source_left_out, target_left_out); an initial guess or prior beyond it is
/// refused. Throws InvalidArgument on invalid settings (naming the field), a prior for a strategy
/// other than adaptive or beyond the supported range, a non-rigid initial guess or one whose
/// translation is beyond the range, a side whose every landmark is beyond it, or what the driver
/// throws.
StrategyOutcome run_strategy(const StrategySource& source, const PreparedTarget& target,
                             const StrategyRequest& request);

}  // namespace lmalign
