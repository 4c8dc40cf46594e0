// The registration engine (include/lmalign/registration/pipeline.hpp).
#include "lmalign/registration/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/score.hpp"

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

// The landmarks `indices` of a view, copied out (a refinement on part of them).
struct OwnedPart {
  Points3 positions;
  std::vector<Mat3> covariances_m2;
  SourceView view(const SourceView& of) const { return {&positions, &covariances_m2, of.up}; }
};

OwnedPart part_of(const SourceView& source, const std::vector<std::uint32_t>& indices) {
  OwnedPart p;
  p.positions.reserve(indices.size());
  for (std::uint32_t i : indices) p.positions.push_back((*source.positions)[i]);
  if (source.has_covariances()) {
    p.covariances_m2.reserve(indices.size());
    for (std::uint32_t i : indices) p.covariances_m2.push_back((*source.covariances_m2)[i]);
  }
  return p;
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

std::string to_string(Seam seam) {
  switch (seam) {
    case Seam::kInitialiser:
      return "initialiser";
    case Seam::kMatcher:
      return "matcher";
    case Seam::kRejector:
      return "rejectors";
    case Seam::kKernel:
      return "kernel";
    case Seam::kEstimator:
      return "estimator";
    case Seam::kSchedule:
      return "schedule";
    case Seam::kScorer:
      return "scorer";
    case Seam::kTrustJudge:
      return "trust";
  }
  return "?";
}

SourceLandmarks SourceLandmarks::from_map(const Map& map) {
  map.validate();
  SourceLandmarks s;
  s.positions = map.positions();
  s.covariances_m2 = map.covariances_m2();
  s.up = estimate_up_axis(map);
  return s;
}

FitnessScore Matcher::fitness(const RefineContext& context, StageState* state, const Isometry3& T,
                              double max_range_m) const {
  (void)state;
  return fitness_score(*context.source.positions, context.target->tree(), T, max_range_m);
}

std::vector<SettingRow> engine_settings() {
  return {
      real_setting("fitness.max_range_m", "RegistrationOptions::score_max_range_m",
                   std::numeric_limits<double>::infinity(), SettingBound::above_or_inf(0.0), "m",
                   "range of PCL's fitness score reported at the initial guess and the estimate "
                   "(landmarks farther from every target landmark are not counted)"),
  };
}

// The rows the engine adds when a stage reads the scales.
static std::vector<SettingRow> scale_settings() {
  return {
      real_setting("scales.floor_m", "Scales::floor_m", 0.0, SettingBound::at_least(0.0), "m",
                   "covariance floor added to every pair's combined covariance; 0 = the data's "
                   "(the larger of the two maps' median smallest-axis standard deviation, or half "
                   "the landmark spacing without covariances)"),
      reals_setting(
          "scales.default_up", "Scales::up_source, up_target", {0.0, 0.0, 1.0},
          [] {
            SettingBound b;
            b.min_size = b.max_size = 3;
            return b;
          }(),
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
  if (needs_scales_) {
    const std::vector<double>& up = settings_.reals("scales.default_up");
    const Vec3 u(up[0], up[1], up[2]);
    if (!u.allFinite() || !(u.norm() > 0.0)) {
      throw InvalidArgument("scales.default_up = " + settings_.row("scales.default_up").text(up) +
                            " must be finite and non-zero");
    }
  }
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

Refinement Pipeline::refine(const RefineContext& context, const Hypothesis& start, Phase phase,
                            bool keep_pairs, int history) const {
  Refinement out;
  out.T = start.T_target_source;
  LoopState& loop = out.loop;
  loop.phase = phase;
  std::unique_ptr<StageState> matched = matcher_->begin(context);
  std::unique_ptr<StageState> scheduled = schedule_->begin(context, start, &loop);
  const std::size_t min_pairs = std::max(schedule_->min_pairs(), estimator_->min_pairs());
  const Points3& target_points = context.target->points();
  const Vec3 centre = context.scales != nullptr ? context.scales->source.centre_m : Vec3::Zero();
  Pairs pairs;
  bool last_degenerate = false;
  loop.max_iterations_per_level = start.max_iterations_per_level;
  for (;;) {
    if (!schedule_->may_iterate(loop) ||
        (start.max_iterations > 0 && loop.iterations >= start.max_iterations)) {
      out.termination = TerminationReason::kMaxIterations;
      break;
    }
    loop.sigma.pivot_m = out.T * centre;
    matcher_->match(context, matched.get(), out.T, loop, &pairs);
    for (const auto& r : rejectors_) r->reject(context, &loop, &pairs);
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
      kernel_->weigh(context, loop, pairs, out.T, step.increment, &pairs.weights);
      if (!weights_positive(pairs.weights, pairs.size())) break;
      step = estimator_->solve(context, loop, pairs, current, step.increment);
    }
    if (!step.ok || !is_finite(step.estimate.T_target_source)) {
      out.last_step = step;
      out.has_step = true;
      out.termination = TerminationReason::kDegenerate;
      break;
    }
    last_degenerate = step.degenerate;
    out.T = step.estimate.T_target_source;
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
            matcher_->fitness(context, matched.get(), out.T, settings_.real("fitness.max_range_m"))
                .mean_sq_m2;
      }
      out.history.push_back(rec);
    }
    const TerminationReason reason =
        schedule_->after_step(context, scheduled.get(), step, pairs, &loop);
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
                                 Phase phase) const {
  const OwnedPart part = part_of(context.source, indices);
  RefineContext sub = context;
  sub.source = part.view(context.source);
  return refine(sub, start, phase);
}

Summary Pipeline::run(const SourceView& source, const PreparedTarget& target,
                      const PipelineRequest& request) const {
  const auto t_start = std::chrono::steady_clock::now();
  // --- inputs
  if (source.positions == nullptr || source.positions->empty()) {
    throw InvalidArgument("registration: the source has no landmarks");
  }
  if (target.size() == 0) throw InvalidArgument("registration: the target has no landmarks");
  const Points3& sp = *source.positions;
  // The supported range (core/supported_range.hpp; align() of presets.hpp leaves such landmarks
  // out).
  for (const auto& [side, points] :
       {std::pair<const char*, const Points3*>{"source", &sp}, {"target", &target.points()}}) {
    for (std::size_t i = 0; i < points->size(); ++i) {
      if (!within_supported_range((*points)[i])) {
        throw InvalidArgument(std::string("registration: ") + side + " landmark " +
                              std::to_string(i) + " is not finite or beyond " +
                              message_number(kMaxCoordinateM) + " m");
      }
    }
  }
  if (source.has_covariances() && source.covariances_m2->size() != sp.size()) {
    throw InvalidArgument("registration: " + std::to_string(source.covariances_m2->size()) +
                          " source covariances for " + std::to_string(sp.size()) + " landmarks");
  }
  std::string why;
  if (request.prior && !request.prior->is_valid(&why)) throw InvalidArgument(why);
  if (request.prior && !initialiser_->uses_prior()) {
    throw InvalidArgument("prior sigma: the initialiser '" + spec_.initialiser + "' of '" +
                          spec_.name + "' uses no prior");
  }
  if (request.initial_guess && !is_finite(*request.initial_guess)) {
    throw InvalidArgument("initial guess: not finite");
  }
  if (request.initial_guess) {
    check_supported_translation("initial guess", request.initial_guess->translation());
  }

  Summary s;
  s.preset = spec_.name;
  s.stages = spec_;
  for (const SettingRow& row : settings_.table()) {
    s.settings.emplace_back(row.key, row.text(settings_.value(row.key)));
  }
  const Isometry3 guess = request.initial_guess.value_or(Isometry3::Identity());
  RegistrationResult& reg = s.registration;
  reg.T_target_source = guess;
  const double range = settings_.real("fitness.max_range_m");
  auto stamp = [&]() {
    reg.wall_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  };

  RefineContext all;
  all.source = source;
  all.target = &target;
  all.init = &s.initialisation;

  // --- scales
  Scales scales;
  if (needs_scales_) {
    if (sp.size() < 3 || target.size() < 3) {
      reg.termination = TerminationReason::kNoCorrespondences;
      s.verdict.reason = "fewer than 3 landmarks in a map";
      stamp();
      s.total_time_s = reg.wall_time_s;
      return s;
    }
    scales.source = estimate_data_scales(sp, source.covariances_m2);
    const std::vector<Mat3>* tgt_cov =
        target.has_covariances() ? &target.covariances_m2() : nullptr;
    scales.target = estimate_data_scales(target.points(), tgt_cov, 4096, &target.tree());
    const double floor_setting = settings_.real("scales.floor_m");
    scales.floor_m = floor_setting > 0.0 ? floor_setting
                                         : std::max(scales.source.floor_m, scales.target.floor_m);
    const std::vector<double>& up = settings_.reals("scales.default_up");
    const Vec3 default_up(up[0], up[1], up[2]);
    scales.up_source = source.up.value_or(default_up).normalized();
    scales.up_target = target.up_axis().value_or(default_up).normalized();
    s.scales = scales;
    all.scales = &*s.scales;
  }

  // --- hypotheses
  InitialiserContext ic;
  ic.source = source;
  ic.target = &target;
  ic.scales = all.scales;
  ic.initial_guess = request.initial_guess;
  if (request.prior) {
    ic.prior_sigma_deg_m =
        std::make_pair(request.prior->rotation_deg, request.prior->translation_m);
  }
  ic.pipeline = this;
  ic.refine_context = &all;
  const std::vector<Hypothesis> hypotheses = initialiser_->propose(ic, &s.initialisation);
  if (hypotheses.empty()) throw Error("initialiser '" + spec_.initialiser + "' proposed nothing");

  // --- with a scorer: refine and score every hypothesis on its samples, one per thread
  Hypothesis best = hypotheses.front();
  int total_iterations = 0;
  if (scorer_ != nullptr) {
    const std::vector<std::uint32_t> samples = scorer_->samples(sp.size());
    const OwnedPart part = part_of(source, samples);
    RefineContext sub = all;
    sub.source = part.view(source);
    std::vector<RefinedHypothesis> refined(hypotheses.size());
    FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(hypotheses.size()); ++i) {
      error.capture([&] {
        const Hypothesis& h = hypotheses[static_cast<std::size_t>(i)];
        const Refinement r = refine(sub, h, Phase::kHypothesis);
        RefinedHypothesis& out = refined[static_cast<std::size_t>(i)];
        out.start = h;
        out.T_refined = r.T;
        out.iterations = r.iterations;
        out.termination = r.termination;
        out.score = scorer_->score(sub, *this, r.T);
      });
    }
    error.rethrow();
    for (const RefinedHypothesis& r : refined) total_iterations += r.iterations;
    std::stable_sort(
        refined.begin(), refined.end(),
        [](const RefinedHypothesis& a, const RefinedHypothesis& b) { return a.score > b.score; });
    s.hypotheses = std::move(refined);
    best = s.hypotheses.front().start;
    best.T_target_source = s.hypotheses.front().T_refined;
  }

  // --- the best on every landmark
  const int history = request.record_history ? (request.history_scores ? 2 : 1) : 0;
  const Schedule::EndPass end = schedule_->end_pass();
  Refinement fin = refine(all, best, Phase::kFinal, end == Schedule::EndPass::kLastStep, history);
  reg.T_target_source = fin.T;
  reg.termination = fin.termination;
  reg.converged = fin.termination == TerminationReason::kTransform ||
                  fin.termination == TerminationReason::kAbsoluteMse ||
                  fin.termination == TerminationReason::kRelativeMse;
  reg.iterations = total_iterations + fin.iterations;
  reg.num_correspondences = fin.num_pairs;
  reg.history = std::move(fin.history);
  {
    // PCL's fitness scores, through the matcher's caches where it keeps them.
    std::unique_ptr<StageState> state = matcher_->begin(all);
    reg.initial_score_m2 = matcher_->fitness(all, state.get(), guess, range).mean_sq_m2;
    reg.final_score_m2 = matcher_->fitness(all, state.get(), fin.T, range).mean_sq_m2;
  }

  // --- covariance and diagnostics
  Pose estimate;
  estimate.T_target_source = fin.T;
  if (end == Schedule::EndPass::kAtEstimate) {
    LoopState loop = fin.loop;
    loop.final_pass = true;
    loop.sigma.pivot_m =
        fin.T * (all.scales != nullptr ? all.scales->source.centre_m : Vec3::Zero());
    std::unique_ptr<StageState> state = matcher_->begin(all);
    Pairs pairs;
    matcher_->match(all, state.get(), fin.T, loop, &pairs);
    for (const auto& r : rejectors_) r->reject(all, &loop, &pairs);
    EstimateDiagnostics& d = s.at_estimate;
    d.computed = true;
    d.num_pairs = pairs.size();
    d.max_distance_m = loop.max_distance_m;
    d.overlap_ratio = fin.loop.overlap_ratio;
    d.inlier_ratio = static_cast<double>(pairs.size()) / static_cast<double>(sp.size());
    if (pairs.size() > 0) {
      loop.distribution_step = estimator_->distribution_step(loop);
      kernel_->weigh(all, loop, pairs, fin.T, Isometry3::Identity(), &pairs.weights);
      double wsum = 0.0, wr2 = 0.0;
      for (std::size_t i = 0; i < pairs.size(); ++i) {
        const double w = pairs.weights.empty() ? 1.0 : pairs.weights[i];
        const double d2 =
            pairs.kind == Pairs::Kind::kPoints
                ? pairs.points[i].distance_sq_m2
                : (target.points()[pairs.gated[i].target_index] - pairs.gated[i].moved_source_m)
                      .squaredNorm();
        wsum += w;
        wr2 += w * d2;
      }
      d.inlier_rms_m = wsum > 0.0 ? std::sqrt(wr2 / wsum) : 0.0;
      if (wsum > 0.0) {
        s.estimator_covariance =
            estimator_->covariance(all, *this, loop, pairs, estimate, nullptr, &s.num_half_samples);
      }
    }
  } else if (end == Schedule::EndPass::kLastStep && fin.has_step && fin.last_step.ok) {
    s.estimator_covariance = estimator_->covariance(all, *this, fin.loop, fin.last_pairs, estimate,
                                                    &fin.last_step, &s.num_half_samples);
  }
  s.covariance = s.estimator_covariance;
  stamp();  // the alignment's time; the verdict's is in total_time_s

  // --- trust
  if (trust_ != nullptr) {
    JudgeContext jc;
    jc.context = all;
    jc.pipeline = this;
    jc.final = &fin;
    jc.hypotheses = &s.hypotheses;
    jc.init = &s.initialisation;
    jc.covariance = &s.estimator_covariance;
    s.verdict = trust_->judge(jc);
    if (s.verdict.covariance) s.covariance = *s.verdict.covariance;
  }
  s.total_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return s;
}

}  // namespace lmalign
