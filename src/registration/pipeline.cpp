// The registration engine (include/lmalign/registration/pipeline.hpp).
#include "lmalign/registration/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/score.hpp"
#include "pipeline_run.hpp"
#include "stages/stage.hpp"

namespace lmalign {

namespace {

template <typename T>
std::unique_ptr<T> build(Seam seam, const std::string& name, const Settings& settings) {
  const StageInfo* info = find_stage(seam, name);
  std::unique_ptr<Stage> stage = info->make(settings);
  if (!stage) return nullptr;  // "none"
  stage->set_name(name);
  std::unique_ptr<T> out(dynamic_cast<T*>(stage.get()));
  if (!out) throw Error("stage registry: '" + name + "' is not a " + to_string(seam));
  stage.release();
  return out;
}

const StageInfo& lookup(Seam seam, const std::string& name) {
  const StageInfo* info = find_stage(seam, name);
  if (info == nullptr) {
    std::string known;
    for (const StageInfo& s : stage_registry()) {
      if (s.seam == seam) known += (known.empty() ? "" : ", ") + s.name;
    }
    throw InvalidArgument("unknown " + to_string(seam) + " stage '" + name + "' (known: " + known +
                          ")");
  }
  return *info;
}

bool weights_positive(const std::vector<double>& weights, std::size_t num_pairs) {
  if (weights.empty()) return num_pairs > 0;
  double sum = 0.0;
  for (double w : weights) sum += w;
  return sum > 0.0;
}

double mean_squared_distance(const Pairs& pairs, const Points3& target_points) {
  if (pairs.kind == Pairs::Kind::kPoints) return correspondence_mse_m2(pairs.points);
  if (pairs.gated.empty()) return 0.0;
  double sum = 0.0;
  for (const GatedPair& g : pairs.gated) {
    sum += (target_points[g.target_index] - g.moved_source_m).squaredNorm();
  }
  return sum / static_cast<double>(pairs.gated.size());
}

}  // namespace

bool PriorSigma::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (!(rotation_deg >= kMinSigma && rotation_deg <= kMaxAngleDeg)) {
    return fail("prior rotation sigma must be within the supported range [" +
                message_number(kMinSigma) + ", " + message_number(kMaxAngleDeg) +
                "] degrees, got " + message_number(rotation_deg));
  }
  if (!(translation_m >= kMinSigma && translation_m <= kMaxCoordinateM)) {
    return fail("prior translation sigma must be within the supported range [" +
                message_number(kMinSigma) + ", " + message_number(kMaxCoordinateM) +
                "] metres, got " + message_number(translation_m));
  }
  return true;
}

std::vector<SettingRow> engine_settings() {
  std::vector<SettingRow> rows{
      real_setting("fitness.max_range_m", "fitness_score(..., max_range_m)",
                   std::numeric_limits<double>::infinity(), SettingBound::above_or_inf(0.0), "m",
                   "range of PCL's fitness score reported at the initial guess and the estimate "
                   "(landmarks farther from every target landmark are not counted)"),
  };
  for (SettingRow& row : scale_search_settings()) rows.push_back(std::move(row));
  return rows;
}

// The rows the engine adds when a stage reads the scales.
static std::vector<SettingRow> scale_settings() {
  const Scales d;
  return {
      real_setting("scales.floor_m", "Scales::floor_m", d.floor_m, SettingBound::at_least(0.0), "m",
                   "covariance floor added to every pair's combined covariance; 0 = the data's "
                   "(the larger of the two maps' median smallest-axis standard deviation, or half "
                   "the landmark spacing without covariances)"),
      real_setting("scales.evidence_spacings", "Scales::evidence_spacings", d.evidence_spacings,
                   SettingBound::at_least(0.0), "1",
                   "each map's evidence scale e is this many of its landmark spacings, or "
                   "scales.evidence_typical_sigmas typical pairs' standard deviations where "
                   "larger; a gated pair whose combined standard deviation, each map's part in "
                   "units of its e, exceeds 1 (rho, the geometric mean over its axes) counts "
                   "rho^-3 of its 1 - d^2 / chi2 in the gated score: its gate holds that many "
                   "landmarks by chance; 0: every pair counts fully (docs/accuracy.md, \"A pair "
                   "counts what it can tell\")"),
      real_setting("scales.evidence_typical_sigmas", "Scales::evidence_typical_sigmas",
                   d.evidence_typical_sigmas, SettingBound::at_least(0.0), "1",
                   "each map's evidence scale is at least this many times the standard deviation "
                   "of a pair of two of its typical landmarks (sqrt(2) x its median landmark "
                   "standard deviation with its floor): where every landmark is vaguer than the "
                   "spacing, only the vague tail is weighed down"),
      reals_setting("scales.default_up", "Scales::up_source, up_target",
                    {d.up_source.x(), d.up_source.y(), d.up_source.z()}, stages::vector3_bound(),
                    "1", "up axis of a map whose frames do not give one (normalised)"),
  };
}

Pipeline::~Pipeline() = default;
Pipeline::Pipeline(Pipeline&&) noexcept = default;
Pipeline& Pipeline::operator=(Pipeline&&) noexcept = default;

Pipeline::Pipeline(const PipelineSpec& spec) : spec_(spec) {
  // The stages' registry rows, in seam order.
  std::vector<std::pair<Seam, std::string>> names{{Seam::kInitialiser, spec.initialiser},
                                                  {Seam::kMatcher, spec.matcher}};
  for (const std::string& r : spec.rejectors) names.emplace_back(Seam::kRejector, r);
  names.insert(names.end(), {{Seam::kKernel, spec.kernel},
                             {Seam::kEstimator, spec.estimator},
                             {Seam::kSchedule, spec.schedule},
                             {Seam::kScorer, spec.scorer},
                             {Seam::kTrustJudge, spec.trust}});
  std::vector<SettingRow> table = engine_settings();
  std::vector<std::string> owner(table.size(), "the engine");
  for (const auto& [seam, name] : names) {
    const StageInfo& info = lookup(seam, name);
    for (SettingRow& row : info.settings()) {
      for (std::size_t i = 0; i < table.size(); ++i) {
        if (table[i].key == row.key) {
          if (owner[i] == name) {
            throw InvalidArgument("pipeline '" + spec.name + "': the stage '" + name +
                                  "' is listed twice");
          }
          throw InvalidArgument("pipeline '" + spec.name + "': the stages '" + owner[i] +
                                "' and '" + name + "' both declare the setting '" + row.key + "'");
        }
      }
      table.push_back(std::move(row));
      owner.push_back(name);
    }
  }
  // Build once without the scale rows to learn whether any stage reads the scales.
  {
    Settings defaults(table);
    initialiser_ = build<Initialiser>(Seam::kInitialiser, spec.initialiser, defaults);
    matcher_ = build<Matcher>(Seam::kMatcher, spec.matcher, defaults);
    estimator_ = build<Estimator>(Seam::kEstimator, spec.estimator, defaults);
    schedule_ = build<Schedule>(Seam::kSchedule, spec.schedule, defaults);
    scorer_ = build<Scorer>(Seam::kScorer, spec.scorer, defaults);
    trust_ = build<TrustJudge>(Seam::kTrustJudge, spec.trust, defaults);
    needs_scales_ = initialiser_->needs_scales() || matcher_->needs_scales() ||
                    estimator_->needs_scales() || schedule_->needs_scales() ||
                    (scorer_ && scorer_->needs_scales()) || (trust_ && trust_->needs_scales());
  }
  if (needs_scales_) {
    for (SettingRow& row : scale_settings()) table.push_back(std::move(row));
  }
  settings_ = Settings(std::move(table));
  for (const auto& [key, value] : spec.settings) {
    if (!settings_.has(key)) {
      const std::string near = settings_.nearest_key(key);
      throw InvalidArgument("unknown setting '" + key + "' for '" + spec.name + "'" +
                            (near.empty() ? std::string() : " (nearest: '" + near + "')"));
    }
    settings_.set(key, value);
  }
  if (needs_scales_) stages::unit_vector(settings_, "scales.default_up");  // checked here
  initialiser_ = build<Initialiser>(Seam::kInitialiser, spec.initialiser, settings_);
  matcher_ = build<Matcher>(Seam::kMatcher, spec.matcher, settings_);
  for (const std::string& r : spec.rejectors) {
    rejectors_.push_back(build<Rejector>(Seam::kRejector, r, settings_));
  }
  kernel_ = build<Kernel>(Seam::kKernel, spec.kernel, settings_);
  estimator_ = build<Estimator>(Seam::kEstimator, spec.estimator, settings_);
  schedule_ = build<Schedule>(Seam::kSchedule, spec.schedule, settings_);
  scorer_ = build<Scorer>(Seam::kScorer, spec.scorer, settings_);
  trust_ = build<TrustJudge>(Seam::kTrustJudge, spec.trust, settings_);
  const int kind = static_cast<int>(matcher_->kind());
  const char* kind_text =
      matcher_->kind() == Pairs::Kind::kPoints ? "point pairs" : "pairs with their covariances";
  std::vector<std::pair<Seam, const Stage*>> others{{Seam::kKernel, kernel_.get()},
                                                    {Seam::kScorer, scorer_.get()},
                                                    {Seam::kTrustJudge, trust_.get()}};
  for (const auto& r : rejectors_) others.emplace_back(Seam::kRejector, r.get());
  for (const auto& [seam, stage] : others) {
    if (stage != nullptr && !stage->accepts(kind)) {
      throw InvalidArgument("pipeline '" + spec.name + "': the " + to_string(seam) + " stage '" +
                            stage->name() + "' does not take the " + kind_text +
                            " of the matcher '" + spec.matcher + "'");
    }
  }
  if (estimator_->needs() != matcher_->kind()) {
    const bool distributions = estimator_->needs() == Pairs::Kind::kDistributions;
    throw InvalidArgument(
        "pipeline '" + spec.name + "': the estimator '" + spec.estimator + "' needs " +
        (distributions ? "pairs with their covariances (a matcher such as 'mahalanobis_gate')"
                       : "point pairs (a matcher such as 'nearest')") +
        ", and the matcher '" + spec.matcher + "' gives " +
        (distributions ? "point pairs" : "pairs with covariances"));
  }
}

std::vector<WeightKind> Pipeline::confidences() const {
  std::vector<const Stage*> stages{initialiser_.get(), matcher_.get()};
  for (const auto& r : rejectors_) stages.push_back(r.get());
  stages.insert(stages.end(),
                {kernel_.get(), estimator_.get(), schedule_.get(), scorer_.get(), trust_.get()});
  std::vector<WeightKind> out;
  for (const Stage* stage : stages) {
    if (stage == nullptr) continue;
    const WeightKind kind = stage->confidence();
    if (kind != WeightKind::kUniform && std::find(out.begin(), out.end(), kind) == out.end()) {
      out.push_back(kind);
    }
  }
  return out;
}

bool Pipeline::uses_covariances() const {
  const std::vector<WeightKind> kinds = confidences();
  return matcher_->kind() == Pairs::Kind::kDistributions ||
         std::find(kinds.begin(), kinds.end(), WeightKind::kCovariance) != kinds.end();
}

Refinement Pipeline::refine(const RefineContext& context, const Hypothesis& start, Phase phase,
                            bool keep_pairs, int history, StageState* matcher_state) const {
  // A free-scale refinement (not a hypothesis': the search's scale is the scale axis's) works on
  // a copy of its source, rescaled each time a 7-DoF step changes the scale.
  const bool free =
      context.free_scale && estimator_->estimates_scale() && phase != Phase::kHypothesis;
  std::unique_ptr<detail::ScaledSource> working;
  RefineContext c = context;
  if (free) {
    working = std::make_unique<detail::ScaledSource>(context.source, context.scales,
                                                     detail::floor_is_a_setting(settings_), 1.0);
    c = working->context(context);
  }
  // A free scale has settled too before the refinement ends: by the schedule's own measure where
  // it has one (Schedule::settles_scale), else by scale.settle.
  const bool settle_here = free && !schedule_->settles_scale();
  const double scale_settle = settle_here ? settings_.real("scale.settle") : 0.0;
  Refinement out;
  out.T = start.T_target_source;
  LoopState& loop = out.loop;
  loop.phase = phase;
  loop.free_scale = free;
  // A free-scale refinement matches its rescaled copy with a state of its own, unless the
  // matcher's state follows the source as it moves (Matcher::state_follows_the_source).
  const bool follows = matcher_->state_follows_the_source();
  const bool shared = matcher_state != nullptr && (!free || follows);
  std::unique_ptr<StageState> own_matched = shared ? nullptr : matcher_->begin(c);
  StageState* matched = shared ? matcher_state : own_matched.get();
  std::unique_ptr<StageState> scheduled = schedule_->begin(c, start, &loop);
  const std::size_t min_pairs = std::max(schedule_->min_pairs(), estimator_->min_pairs());
  const Points3& target_points = c.target->points();
  Pairs pairs;
  bool last_degenerate = false;
  loop.max_iterations_per_level = start.max_iterations_per_level;
  for (;;) {
    if (!schedule_->may_iterate(loop) ||
        (start.max_iterations > 0 && loop.iterations >= start.max_iterations)) {
      out.termination = TerminationReason::kMaxIterations;
      break;
    }
    loop.sigma.pivot_m = out.T * (c.scales != nullptr ? c.scales->source.centre_m : Vec3::Zero());
    matcher_->match(c, matched, out.T, loop, &pairs);
    for (const auto& r : rejectors_) r->reject(c, &loop, &pairs);
    out.num_pairs = pairs.size();
    if (pairs.size() < min_pairs) {
      out.termination = TerminationReason::kNoCorrespondences;
      break;
    }
    // Weigh and estimate, re-weighting on the fixed pairs (iteratively re-weighted least
    // squares); a weighting that sums to zero keeps the last step.
    loop.distribution_step = estimator_->distribution_step(loop);
    Pose current;
    current.T_target_source = out.T;
    Step step;
    step.estimate = current;
    const int reweightings = kernel_->reweightings();
    for (int it = 0; it < reweightings; ++it) {
      kernel_->weigh(c, loop, pairs, out.T, step.increment, &pairs.weights);
      if (!weights_positive(pairs.weights, pairs.size())) break;
      step = estimator_->solve(c, loop, pairs, current, step.increment);
    }
    if (!step.ok || !is_finite(step.estimate.T_target_source) || !(step.estimate.scale > 0.0) ||
        !std::isfinite(step.estimate.scale)) {
      out.last_step = step;
      out.has_step = true;
      out.termination = TerminationReason::kDegenerate;
      break;
    }
    last_degenerate = step.degenerate;
    out.T = step.estimate.T_target_source;
    if (free && step.estimate.scale != 1.0) {
      out.scale *= step.estimate.scale;
      working->set_scale(out.scale);
      // The source moved in place: caches keyed by its positions start again, unless they check
      // every seed against where the landmark now is.
      if (!follows) {
        own_matched = matcher_->begin(c);
        matched = own_matched.get();
      }
    }
    ++loop.iterations;
    ++loop.level_iterations;
    out.iterations = loop.iterations;
    if (history > 0) {
      IterationRecord rec;
      rec.iteration = loop.iterations;
      rec.num_correspondences = pairs.size();
      rec.mse_m2 = mean_squared_distance(pairs, target_points);
      if (history > 1) {
        rec.score_m2 =
            matcher_->fitness(c, matched, out.T, settings_.real("fitness.max_range_m")).mean_sq_m2;
      }
      out.history.push_back(rec);
    }
    TerminationReason reason = schedule_->after_step(c, scheduled.get(), step, pairs, &loop);
    // A free scale has settled too before the refinement ends (within the schedule's budget).
    if (settle_here && reason != TerminationReason::kNotTerminated &&
        reason != TerminationReason::kMaxIterations &&
        std::abs(std::log(step.estimate.scale)) > scale_settle && schedule_->may_iterate(loop)) {
      reason = TerminationReason::kNotTerminated;
    }
    out.last_step = step;
    out.has_step = true;
    if (reason != TerminationReason::kNotTerminated) {
      out.termination = reason;
      break;
    }
  }
  out.termination = schedule_->finish(out.termination, last_degenerate);
  out.iterations = loop.iterations;
  if (keep_pairs) out.last_pairs = std::move(pairs);
  return out;
}

Refinement Pipeline::refine_part(const RefineContext& context,
                                 const std::vector<std::uint32_t>& indices, const Hypothesis& start,
                                 Phase phase, const StageState* whole_matcher_state) const {
  const detail::OwnedPart part = detail::part_of(context.source, indices);
  RefineContext sub = context;
  sub.source = part.view(context.source);
  const std::unique_ptr<StageState> seeded =
      whole_matcher_state != nullptr ? matcher_->part_state(*whole_matcher_state, indices)
                                     : nullptr;
  return refine(sub, start, phase, false, 0, seeded.get());
}

Summary Pipeline::run(const SourceView& source, const PreparedTarget& target,
                      const PipelineRequest& request) const {
  detail::PipelineRun run(*this, source, target, request);
  run.validate();
  if (!run.begin_search(1.0)) return run.unanswered();
  Summary first = run.conclude(1.0, true);  // may be kept for settle()
  int attempts = 1;
  int searches = 1;
  const bool judged = trust_ != nullptr && run.scale_free();
  // A free scale's poses so far, which a later scale's answer is weighed against
  // (PipelineRun::weigh_earlier_scales).
  std::vector<detail::PipelineRun::ScalePose> earlier;
  // A search again at `factor` (the pass the run is at), concluded at its own initial scale and
  // weighed against the earlier scales; none when it cannot begin.
  const auto search_again = [&](double factor) -> std::optional<Summary> {
    if (!run.begin_search(factor)) return std::nullopt;
    Summary tried = run.conclude(1.0);
    ++attempts;
    ++searches;
    run.weigh_earlier_scales(&tried, earlier);
    return tried;
  };
  // A free scale whose first pass gives no trusted answer, without a prior: the first passes at
  // the other scales of the searches again come before any complete search (docs/scale.md,
  // step 6). A first pass costs a fraction of a complete search, and a wrong initial scale is
  // why most first passes of a free scale fail (desk_retri_60_sim3: the initial scale 13% off,
  // the truth's first pass trusted a rung away). A trusted answer there is checked as the first
  // scale's would be (goes_deeper: the complete search at its scale). None: the complete search
  // (after one more first pass half a rung from the best, towards its better neighbour:
  // scale.half_rung) at the scale whose first pass scored highest, with that answer among its
  // hypotheses; its rungs follow below, and no complete search at the other scales (measured on
  // 55 Sim(3) pairs: none of those searches gave a trusted answer, and they cost 2-8 s a pair).
  bool searched_again = false;
  if (judged && !request.initial_guess && run.first_pass() && !first.verdict.trustworthy &&
      run.goes_deeper(first)) {
    const bool deferred = run.deferred();
    detail::PipelineRun::add_scale_poses(first, &earlier);
    double best_factor = 1.0;
    double best_score = first.verdict.score;
    Isometry3 best_T = first.registration.T_target_source;
    std::vector<std::pair<double, double>> scored{{1.0, first.verdict.score}};
    // The first pass at `factor`: its answer when trusted (after its check), else none.
    const auto first_pass_at = [&](double factor) -> std::optional<Summary> {
      std::optional<Summary> found = search_again(factor);
      if (!found) return std::nullopt;
      Summary tried = std::move(*found);
      if (tried.verdict.trustworthy && run.goes_deeper(tried)) {
        // Its check (no prior here): the complete search at its scale, the answer among its
        // hypotheses. Counted as a pass, not as another search.
        run.deepen(tried.registration.T_target_source, true, factor);
        if (run.begin_search(factor)) {
          tried = run.conclude(1.0);
          tried.initialisation.notes.emplace_back("deeper pass to check a trusted answer", 1.0);
          run.weigh_earlier_scales(&tried, earlier);
        }
        run.restart_first_pass();
      }
      if (tried.verdict.trustworthy) return tried;
      detail::PipelineRun::add_scale_poses(tried, &earlier);
      scored.emplace_back(factor, tried.verdict.score);
      if (tried.verdict.score > best_score) {
        best_score = tried.verdict.score;
        best_factor = factor;
        best_T = tried.registration.T_target_source;
      }
      return std::nullopt;
    };
    for (const ScaleAttempt& a : run.scale_search().researches(first.scale.scale)) {
      if (std::optional<Summary> t = first_pass_at(a.factor))
        return run.finish(std::move(*t), attempts, searches);
    }
    // None trusted: one more first pass, half a rung from the best towards its better
    // neighbour (scale.half_rung), before the complete search.
    if (const std::optional<double> half = run.scale_search().half_rung(scored)) {
      if (std::optional<Summary> t = first_pass_at(*half))
        return run.finish(std::move(*t), attempts, searches);
    }
    // Should the complete search not begin, the first pass's answer is the result, judged
    // without the covariance's resampling: it was untrusted without it, so it is with it
    // (PipelineRun::deeper_either_way).
    searched_again = true;
    run.deepen(best_T, false, best_factor);
    if (!run.begin_search(best_factor)) return run.finish(std::move(first), attempts, searches);
    first = run.conclude(1.0);
    first.initialisation.notes.emplace_back("deeper pass after an untrusted answer", 1.0);
    first.initialisation.notes.emplace_back("first passes at other scales", attempts - 1.0);
    if (deferred)
      first.initialisation.notes.emplace_back("previous pass without half samples", 1.0);
  }
  // The initialiser's deeper passes (docs/accuracy.md, "The first pass"): the first pass (the
  // correspondence search's poses alone) gave no trusted answer, or a trusted one inside a
  // prior's window that none of the maps' own poses confirmed, or one whose residuals exceed
  // their covariances as an alias's (Verdict::rivals_needed: the alias test needs every rival,
  // and the first pass's few poses may miss them): the next pass (the complete
  // search; with init.prior_complete_search = "check" the prior's search comes first, then the
  // correspondence poses, then the complete search), whose answer is the result. Not when the
  // maps put the answer outside a prior's window and every other test trusts it: no deeper pass
  // makes that result trusted; nor, with "check", when the correspondence poses' answer is not
  // trusted (InitialiserReport::deeper_if_untrusted), or when no landmark supports the prior's
  // own answer (deeper_needs_evidence, Verdict::no_evidence). Not counted among the scale axis's
  // searches and attempts.
  while (run.first_pass()) {
    const bool checks = first.verdict.trustworthy;
    if (!run.goes_deeper(first)) break;
    const bool deferred = run.deferred();
    // The answer stays among the next pass's hypotheses, trusted (then checked) or not: the
    // next pass may find its rivals, never lose it. (Untrusted answers were dropped until
    // 2026-11-26: on a simulated road with 25% overlap the first pass found the truth, refused
    // for a rival at 85%, and the complete search then answered 47 m off, scoring 13% less.)
    // A check (of a trusted answer) that the maps' own poses confirmed, not on the prior's word
    // alone: InitialiserContext::checking.
    run.deepen(first.registration.T_target_source,
               checks && !run.prior_unconfirmed() && !first.verdict.alias_waived_by_prior);
    if (!run.begin_search(1.0)) {
      first = run.settle(std::move(first));  // its verdict with the covariance's resampling
      break;
    }
    first = run.conclude(1.0, true);
    // A previous pass judged without the covariance's half samples (PipelineRun::
    // deeper_either_way: this pass replaces it whatever they would have said) was trusted only
    // as far as the tests before them go.
    first.initialisation.notes.emplace_back(
        !checks    ? "deeper pass after an untrusted answer"
        : deferred ? "deeper pass to check an answer trusted without half samples"
                   : "deeper pass to check a trusted answer",
        1.0);
    if (deferred)
      first.initialisation.notes.emplace_back("previous pass without half samples", 1.0);
  }
  if (!judged || first.verdict.trustworthy) return run.finish(std::move(first), attempts, searches);
  // The scale axis (ScaleSearch, docs/scale.md): the first search's hypotheses concluded at its
  // rungs, then searches again at other initial scales (unless their first passes came first,
  // above), while none is trusted. The first trusted result wins; none: the first.
  // An answer at a later scale is weighed against the poses the earlier scales found, as
  // against its own rivals (PipelineRun::weigh_earlier_scales).
  const ScaleSearch& scales = run.scale_search();
  detail::PipelineRun::add_scale_poses(first, &earlier);
  if (scorer_ != nullptr) {
    for (const ScaleAttempt& a : scales.rungs()) {
      if (a.factor == 1.0) continue;
      Summary tried = run.conclude(a.factor);
      ++attempts;
      run.weigh_earlier_scales(&tried, earlier);
      if (tried.verdict.trustworthy) return run.finish(std::move(tried), attempts, searches);
      detail::PipelineRun::add_scale_poses(tried, &earlier);
    }
  }
  for (const ScaleAttempt& a : scales.researches(first.scale.scale)) {
    if (searched_again) break;  // their first passes came first (above)
    std::optional<Summary> tried = search_again(a.factor);
    if (!tried) continue;
    if (tried->verdict.trustworthy) return run.finish(std::move(*tried), attempts, searches);
    detail::PipelineRun::add_scale_poses(*tried, &earlier);
  }
  return run.finish(std::move(first), attempts, searches);
}

}  // namespace lmalign
