#include "lmalign/registration/strategy.hpp"

#include <limits>

#include "lmalign/core/error.hpp"
#include "lmalign/registration/robust.hpp"

namespace lmalign {

StrategyOutcome run_strategy(const StrategySource& source, const PreparedTarget& target,
                             const StrategyRequest& request) {
  if (request.initial_guess && !is_rigid_transform(*request.initial_guess)) {
    throw InvalidArgument(
        "initial guess: not a rigid transform (expected a finite 4x4 [R t; 0 0 0 1] with R "
        "orthonormal and det R = +1)");
  }
  if (request.prior && request.strategy != PaperStrategy::kAdaptive) {
    throw InvalidArgument("prior sigma: only the adaptive strategy uses a prior (got '" +
                          to_string(request.strategy) + "')");
  }
  const Isometry3 init = request.initial_guess.value_or(Isometry3::Identity());
  StrategyOutcome out;
  if (request.strategy == PaperStrategy::kAdaptive) {
    SourceLandmarks s;
    s.positions = source.positions;
    s.covariances_m2 = source.covariances_m2;
    s.up = source.up;
    AdaptiveOptions o;
    if (request.max_iterations) o.max_iterations = *request.max_iterations;
    const AdaptiveResult r =
        align_adaptive(s, target, o, request.initial_guess ? &*request.initial_guess : nullptr,
                       request.prior ? &*request.prior : nullptr);
    out.result = r.registration;
    out.trustworthy = r.trustworthy;
    out.trust_reason = r.trust_reason;
    out.covariance = r.covariance;
    out.adaptive = r;
    return out;
  }
  if (is_paper_strategy(request.strategy)) {
    RegistrationOptions o = RegistrationOptions::paper(request.strategy, request.k);
    if (request.max_distance_m) o.max_correspondence_distance_m = *request.max_distance_m;
    if (request.max_iterations) o.convergence.max_iterations = *request.max_iterations;
    o.record_history = request.record_history;
    o.history_scores = request.record_history;
    out.result = align(source.positions, target, o, init);
  } else {
    RobustRegistrationOptions ro = robust_strategy_options(request.strategy, request.k);
    if (request.max_iterations || request.max_distance_m) {
      ro = with_limits(ro, request.max_iterations.value_or(ro.max_iterations),
                       request.max_distance_m.value_or(std::numeric_limits<double>::infinity()));
    }
    out.result = align_robust(source.positions, target, ro, init, &source.covariances_m2);
  }
  PoseCovariance cov;
  const TrustVerdict v =
      judge_alignment(source.positions, target.tree(), out.result.T_target_source, {}, &cov);
  out.trustworthy = v.trustworthy;
  out.trust_reason = v.reason;
  out.covariance = cov;
  out.verdict = v;
  return out;
}

}  // namespace lmalign
