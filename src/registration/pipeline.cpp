// The registration engine (include/lmalign/registration/pipeline.hpp).
#include "lmalign/registration/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/registration/similarity.hpp"

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

// The rungs of a free-scale run's scale axis after its initial scale (relative to it), nearest
// first: concluded without a new search while none is trusted (docs/scale.md, step 5).
constexpr double kScaleRungs[] = {1.0 / 1.12, 1.12};

// The source rescaled by `scale` (positions times s, covariances times s^2).
SourceLandmarks rescaled(const SourceView& source, double scale) {
  SourceLandmarks out;
  out.positions.reserve(source.size());
  for (const Vec3& p : *source.positions) out.positions.push_back(scale * p);
  if (source.has_covariances()) {
    out.covariances_m2.reserve(source.size());
    for (const Mat3& c : *source.covariances_m2) out.covariances_m2.push_back(scale * scale * c);
  }
  out.up = source.up;
  return out;
}

void rescale_in_place(SourceLandmarks* source, double factor) {
  for (Vec3& p : source->positions) p *= factor;
  for (Mat3& c : source->covariances_m2) c *= factor * factor;
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
  static constexpr EnumName<Seam> kNames[] = {
      {Seam::kInitialiser, "initialiser"}, {Seam::kMatcher, "matcher"},
      {Seam::kRejector, "rejectors"},      {Seam::kKernel, "kernel"},
      {Seam::kEstimator, "estimator"},     {Seam::kSchedule, "schedule"},
      {Seam::kScorer, "scorer"},           {Seam::kTrustJudge, "trust"}};
  return name_of(kNames, seam);
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

  // --- free scale: the source rescaled by the data's initial scale (positions by s, covariances
  // by s^2); the rounds below refine the scale as a seventh degree of freedom.
  std::optional<SourceLandmarks> owned;
  ScaleEstimate scale_estimate;
  if (request.free_scale) {
    if (estimator_->degrees_of_freedom() != 6) {
      throw InvalidArgument("scale free: the estimator '" + spec_.estimator + "' of '" +
                            spec_.name + "' estimates " +
                            std::to_string(estimator_->degrees_of_freedom()) +
                            " degrees of freedom; a free scale needs a 6-DoF estimator");
    }
    if (sp.size() < 3 || target.size() < 3) {
      throw InvalidArgument("scale free: fewer than 3 landmarks in a map");
    }
    const DataScales a = estimate_data_scales(sp, source.covariances_m2);
    const std::vector<Mat3>* tgt_cov =
        target.has_covariances() ? &target.covariances_m2() : nullptr;
    const DataScales b = estimate_data_scales(target.points(), tgt_cov, 4096, &target.tree());
    scale_estimate.free = true;
    scale_estimate.initial_scale = initial_scale_from_spacing(a.spacing_m, b.spacing_m);
    if (request.initial_scale) {
      if (!std::isfinite(*request.initial_scale) || !(*request.initial_scale > 0.0)) {
        throw InvalidArgument("initial scale " + message_number(*request.initial_scale) +
                              ": expected finite and > 0");
      }
      scale_estimate.initial_scale = *request.initial_scale;
    }
    scale_estimate.scale = scale_estimate.initial_scale;
    owned = rescaled(source, scale_estimate.scale);
  }
  const SourceView src = owned ? owned->view() : source;

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
  all.source = src;
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
    scales.source = estimate_data_scales(*src.positions, src.covariances_m2);
    const std::vector<Mat3>* tgt_cov =
        target.has_covariances() ? &target.covariances_m2() : nullptr;
    scales.target = estimate_data_scales(target.points(), tgt_cov, 4096, &target.tree());
    const double floor_setting = settings_.real("scales.floor_m");
    scales.floor_m = floor_setting > 0.0 ? floor_setting
                                         : std::max(scales.source.floor_m, scales.target.floor_m);
    const std::vector<double>& up = settings_.reals("scales.default_up");
    const Vec3 default_up(up[0], up[1], up[2]);
    scales.up_source = src.up.value_or(default_up).normalized();
    scales.up_target = target.up_axis().value_or(default_up).normalized();
    s.scales = scales;
    all.scales = &*s.scales;
  }

  // --- hypotheses
  InitialiserContext ic;
  ic.source = src;
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

  // --- with a scorer and a free scale: the scale axis (docs/scale.md, step 5). The initial scale
  // from the spacings can be off by more than the search absorbs (about 6% either way), and a
  // search mode at the right pose but the wrong scale refines no better than a wrong mode. So
  // the hypotheses are concluded at the initial scale, then at each rung of kScaleRungs while
  // none is trusted: the samples' positions times the rung (covariances as they are, so that no
  // rung's gate is wider than another's), each pose moved to keep the source centre where the
  // search put it. Every hypothesis at one rung, so that the trust judge weighs the rivals at the
  // scale of the best (letting each pick its own rung made a wrong pose at a shrunk scale score
  // 87% of the right one on the desk pair). None trusted: the first.
  std::vector<double> rungs{1.0};
  if (owned && scorer_ != nullptr && request.scale_rungs) {
    rungs.insert(rungs.end(), std::begin(kScaleRungs), std::end(kScaleRungs));
  }
  const std::vector<std::uint32_t> samples =
      scorer_ != nullptr ? scorer_->samples(sp.size()) : std::vector<std::uint32_t>{};
  const OwnedPart part = part_of(src, samples);
  std::vector<OwnedPart> rung_parts(rungs.size());
  std::vector<Scales> rung_scales(rungs.size());
  std::vector<RefineContext> rung_context(rungs.size(), all);
  const Vec3 centre = all.scales != nullptr ? all.scales->source.centre_m : Vec3::Zero();
  for (std::size_t k = 0; k < rungs.size(); ++k) {
    rung_parts[k] = part;
    for (Vec3& p : rung_parts[k].positions) p *= rungs[k];
    rung_context[k].source = rung_parts[k].view(src);
    if (all.scales != nullptr) {
      rung_scales[k] = *all.scales;
      DataScales& d = rung_scales[k].source;
      d.centre_m *= rungs[k];
      d.radius_m *= rungs[k];
      d.spacing_m *= rungs[k];
      rung_context[k].scales = &rung_scales[k];
    }
  }
  // The hypotheses at rung k (the pose moved to keep the source centre in place).
  auto at_rung = [&](std::size_t k) {
    std::vector<Hypothesis> out = hypotheses;
    for (Hypothesis& h : out) {
      h.scale_factor = rungs[k];
      h.T_target_source.translation() += (1.0 - rungs[k]) * (h.T_target_source.linear() * centre);
    }
    return out;
  };
  // Refines and scores `tried` at rung k, one per thread.
  auto refine_all = [&](const std::vector<Hypothesis>& tried, std::size_t k) {
    std::vector<RefinedHypothesis> refined(tried.size());
    FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(tried.size()); ++i) {
      error.capture([&] {
        const Hypothesis& h = tried[static_cast<std::size_t>(i)];
        const Refinement r = refine(rung_context[k], h, Phase::kHypothesis);
        RefinedHypothesis& out = refined[static_cast<std::size_t>(i)];
        out.start = h;
        out.T_refined = r.T;
        out.iterations = r.iterations;
        out.termination = r.termination;
        out.score = scorer_->score(rung_context[k], *this, r.T);
      });
    }
    error.rethrow();
    return refined;
  };
  // --- the conclusion at rung k: every hypothesis refined and scored there (with a scorer), the
  // best refined on every landmark (with the scale free: its 7-DoF rounds), its covariance and
  // diagnostics, the trust judge's verdict. On copies of the summary and the source, so that
  // each rung starts from the same state.
  const Summary base = s;
  const std::optional<SourceLandmarks> owned_base = owned;
  const RefineContext all_base = all;
  const ScaleEstimate base_scale = scale_estimate;
  auto conclude = [&](std::size_t rung) -> Summary {
    Summary s = base;
    std::optional<SourceLandmarks> owned = owned_base;
    ScaleEstimate scale_estimate = base_scale;
    const SourceView src = owned ? owned->view() : source;
    RegistrationResult& reg = s.registration;
    auto stamp = [&]() {
      reg.wall_time_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    };
    RefineContext all = all_base;
    all.source = src;
    all.init = &s.initialisation;
    all.scales = s.scales ? &*s.scales : nullptr;
    int total_iterations = 0;
    // The source rescaled in place by `factor` (positions by it, covariances by its square), and
    // the scales read off it with it.
    auto rescale_by = [&](double factor) {
      rescale_in_place(&*owned, factor);
      scale_estimate.scale *= factor;
      if (s.scales) {
        DataScales& d = s.scales->source;
        d.spacing_m *= factor;
        d.floor_m *= factor;
        d.radius_m *= factor;
        d.centre_m *= factor;
        if (!(settings_.real("scales.floor_m") > 0.0)) {
          s.scales->floor_m = std::max(d.floor_m, s.scales->target.floor_m);
        }
      }
    };
    Hypothesis best = hypotheses.front();
    if (scorer_ != nullptr) {
      std::vector<RefinedHypothesis> refined = refine_all(at_rung(rung), rung);
      for (const RefinedHypothesis& r : refined) total_iterations += r.iterations;
      std::stable_sort(
          refined.begin(), refined.end(),
          [](const RefinedHypothesis& a, const RefinedHypothesis& b) { return a.score > b.score; });
      s.hypotheses = std::move(refined);
      best = s.hypotheses.front().start;
      best.T_target_source = s.hypotheses.front().T_refined;
      if (best.scale_factor != 1.0) {
        rescale_by(best.scale_factor);
        best.scale_factor = 1.0;
      }
    }

    // --- the best on every landmark
    const int history = request.record_history ? (request.history_scores ? 2 : 1) : 0;
    const Schedule::EndPass end = schedule_->end_pass();
    Refinement fin = refine(all, best, Phase::kFinal, end == Schedule::EndPass::kLastStep, history);
    if (owned) {
      // --- the scale as a seventh degree of freedom: one 7-DoF step on the pairs at the estimate
      // (Umeyama with scale on point pairs, Gauss-Newton on distribution pairs), the source
      // rescaled by its scale change, and the final refinement again from the step's pose.
      const Vec3 centre_0 = all.scales != nullptr ? all.scales->source.centre_m : Vec3::Zero();
      auto pairs_at = [&](const Isometry3& T, const LoopState& at, Pairs* pairs) {
        LoopState loop = at;
        loop.final_pass = true;
        loop.sigma.pivot_m = T * (all.scales != nullptr ? all.scales->source.centre_m : centre_0);
        std::unique_ptr<StageState> state = matcher_->begin(all);
        matcher_->match(all, state.get(), T, loop, pairs);
        for (const auto& rj : rejectors_) rj->reject(all, &loop, pairs);
        if (pairs->size() > 0) {
          loop.distribution_step = estimator_->distribution_step(loop);
          kernel_->weigh(all, loop, *pairs, T, Isometry3::Identity(), &pairs->weights);
        }
        return loop.sigma.pivot_m;
      };
      // The pairs as (moved, target, information) for the 7-DoF step.
      auto step_at = [&](const Isometry3& T, const LoopState& at,
                         std::optional<Similarity3>* closed_form) {
        Pairs pairs;
        Vec3 pivot = pairs_at(T, at, &pairs);
        Points3 moved, targets;
        std::vector<Mat3> information;
        const Points3& tp = target.points();
        if (pairs.kind == Pairs::Kind::kPoints) {
          for (const Correspondence& c : pairs.points) {
            moved.push_back(pairs.moved[c.source_index]);
            targets.push_back(tp[c.target_index]);
          }
          if (all.scales == nullptr && !moved.empty()) {
            pivot = Vec3::Zero();
            for (const Vec3& m : moved) pivot += m;
            pivot /= static_cast<double>(moved.size());
          }
          if (closed_form != nullptr) {
            *closed_form = umeyama_similarity(moved, targets,
                                              pairs.weights.empty() ? nullptr : &pairs.weights);
          }
        } else {
          for (const GatedPair& g : pairs.gated) {
            moved.push_back(g.moved_source_m);
            targets.push_back(tp[g.target_index]);
            information.push_back(g.information);
          }
        }
        const SimilarityStep st = solve_similarity_step(
            moved, targets, information.empty() ? nullptr : &information, pairs.weights, pivot);
        return std::make_pair(st, pivot);
      };
      // A round: 7-DoF steps, each on the pairs made again at the current similarity (the last
      // refinement's gate), until the scale settles (at most kStepsPerRound); then the final
      // refinement again, from the round's pose at its scale.
      constexpr int kMaxScaleRounds = 20;
      constexpr int kStepsPerRound = 10;
      constexpr double kScaleTolerance = 1e-6;
      for (int round = 0; round < kMaxScaleRounds; ++round) {
        Isometry3 T = fin.T;
        double round_change = 0.0;  // |log| of the round's scale change
        bool moved = false;
        for (int k = 0; k < kStepsPerRound; ++k) {
          std::optional<Similarity3> closed;
          const auto [st, pivot] = step_at(T, fin.loop, &closed);
          Similarity3 dS;
          if (closed) {
            dS = *closed;
          } else if (st.ok) {
            dS = similarity_increment(st.xi, pivot);
          } else {
            break;
          }
          if (!(dS.scale > 0.0) || !std::isfinite(dS.scale) || !dS.matrix().allFinite()) break;
          // p_target = dS (T (s p)) = dR R (ds s p) + ds dR t + dt.
          Isometry3 next = Isometry3::Identity();
          next.linear() = dS.rigid.linear() * T.linear();
          next.translation() =
              dS.scale * (dS.rigid.linear() * T.translation()) + dS.rigid.translation();
          T = next;
          rescale_by(dS.scale);
          moved = true;
          round_change += std::log(dS.scale);
          if (std::abs(std::log(dS.scale)) < kScaleTolerance) break;
        }
        if (!moved) break;
        Hypothesis from = best;
        from.T_target_source = T;
        total_iterations += fin.iterations;
        fin = refine(all, from, Phase::kFinal, end == Schedule::EndPass::kLastStep, history);
        ++scale_estimate.rounds;
        if (std::abs(round_change) < kScaleTolerance) break;
      }
      // The best hypothesis scored again at the refined scale, on the same samples: its rung is
      // up to 6% off, and the trust judge's margin to the rivals (each at its own best rung) must
      // not count that against it.
      if (scorer_ != nullptr && !s.hypotheses.empty()) {
        const OwnedPart part = part_of(src, scorer_->samples(sp.size()));
        RefineContext sub = all;
        sub.source = part.view(src);
        const double at_estimate = scorer_->score(sub, *this, fin.T);
        RefinedHypothesis& front = s.hypotheses.front();
        if (at_estimate > front.score) {
          front.score = at_estimate;
          front.T_refined = fin.T;
        }
      }
      const auto [st, pivot] = step_at(fin.T, fin.loop, nullptr);
      scale_estimate.covariance_7x7 = similarity_covariance(st, pivot);
      if (scale_estimate.covariance_7x7) {
        scale_estimate.scale_sd =
            scale_estimate.scale * std::sqrt((*scale_estimate.covariance_7x7)(6, 6));
      }
    }
    s.scale = scale_estimate;
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
          s.estimator_covariance = estimator_->covariance(all, *this, loop, pairs, estimate,
                                                          nullptr, &s.num_half_samples);
        }
      }
    } else if (end == Schedule::EndPass::kLastStep && fin.has_step && fin.last_step.ok) {
      s.estimator_covariance = estimator_->covariance(
          all, *this, fin.loop, fin.last_pairs, estimate, &fin.last_step, &s.num_half_samples);
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
    return s;
  };

  Summary first;
  for (std::size_t k = 0; k < rungs.size(); ++k) {
    Summary tried = conclude(k);
    tried.scale.attempts = static_cast<int>(k) + 1;
    const bool done = !owned || trust_ == nullptr || tried.verdict.trustworthy;
    if (k == 0) first = std::move(tried);
    if (done) {
      Summary& out = k == 0 ? first : tried;
      out.total_time_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
      return out;
    }
  }
  first.scale.attempts = static_cast<int>(rungs.size());
  first.total_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return first;
}

}  // namespace lmalign
