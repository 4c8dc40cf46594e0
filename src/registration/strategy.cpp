#include "lmalign/registration/strategy.hpp"

#include <limits>

#include "lmalign/core/error.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/supported_landmarks.hpp"

namespace lmalign {

namespace {

StrategyOutcome run_in_range(const StrategySource& source, const PreparedTarget& target,
                             const StrategyRequest& request) {
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

}  // namespace

StrategyOutcome run_strategy(const StrategySource& source, const PreparedTarget& target,
                             const StrategyRequest& request) {
  if (request.initial_guess && !is_rigid_transform(*request.initial_guess)) {
    throw InvalidArgument(
        "initial guess: not a rigid transform (expected a finite 4x4 [R t; 0 0 0 1] with R "
        "orthonormal and det R = +1)");
  }
  if (request.initial_guess) {
    check_supported_translation("initial guess", request.initial_guess->translation());
  }
  if (request.prior && request.strategy != PaperStrategy::kAdaptive) {
    throw InvalidArgument("prior sigma: only the adaptive strategy uses a prior (got '" +
                          to_string(request.strategy) + "')");
  }
  std::string why;
  if (request.prior && !request.prior->is_valid(&why)) throw InvalidArgument("prior sigma: " + why);
  // The supported range (core/supported_range.hpp): landmarks beyond it are left out, counted,
  // and named in the trust reason.
  const SupportedLandmarks kept = keep_supported_landmarks(source, target);
  StrategyOutcome out = run_in_range(kept.source ? *kept.source : source,
                                     kept.target ? *kept.target : target, request);
  out.source_left_out = kept.source_left_out;
  out.target_left_out = kept.target_left_out;
  const std::string note = left_out_message(kept.source_left_out, kept.target_left_out);
  if (!note.empty()) {
    out.trust_reason += "; " + note;
    if (out.adaptive) out.adaptive->trust_reason = out.trust_reason;
    if (out.verdict) out.verdict->reason = out.trust_reason;
  }
  return out;
}

}  // namespace lmalign
