// The phases of one run of a Pipeline (pipeline_run.hpp).
#include "pipeline_run.hpp"

#include "stages/stage.hpp"

#include <algorithm>
#include <cmath>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"

namespace lmalign::detail {

// ----------------------------------------------------------------------------- sources

bool floor_is_a_setting(const Settings& settings) {
  return settings.has("scales.floor_m") && settings.real("scales.floor_m") > 0.0;
}

OwnedPart part_of(const SourceView& source, const std::vector<std::uint32_t>& indices) {
  OwnedPart p;
  p.positions.reserve(indices.size());
  for (std::uint32_t i : indices) p.positions.push_back((*source.positions)[i]);
  if (source.has_covariances()) {
    p.covariances_m2.reserve(indices.size());
    for (std::uint32_t i : indices) p.covariances_m2.push_back((*source.covariances_m2)[i]);
  }
  if (source.has_view_directions()) {
    p.view_directions.reserve(indices.size());
    for (std::uint32_t i : indices) p.view_directions.push_back((*source.view_directions)[i]);
  }
  return p;
}

ScaledSource::ScaledSource(const SourceView& original, const Scales* scales, bool floor_fixed,
                           double scale)
    : original_(original), floor_fixed_(floor_fixed) {
  if (scales != nullptr) original_scales_ = *scales;
  set_scale(scale);
}

void ScaledSource::set_scale(double scale) {
  scale_ = scale;
  const Points3& p = *original_.positions;
  positions_.resize(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) positions_[i] = scale * p[i];
  if (original_.has_covariances()) {
    const std::vector<Mat3>& c = *original_.covariances_m2;
    covariances_.resize(c.size());
    for (std::size_t i = 0; i < c.size(); ++i) covariances_[i] = scale * scale * c[i];
  }
  if (original_scales_) {
    scales_ = original_scales_;
    DataScales& d = scales_->source;
    d.spacing_m *= scale;
    d.floor_m *= scale;
    d.sigma_m *= scale;
    d.radius_m *= scale;
    d.centre_m *= scale;
    if (!floor_fixed_) scales_->floor_m = std::max(d.floor_m, scales_->target.floor_m);
  }
}

RefineContext ScaledSource::context(const RefineContext& of) const {
  RefineContext c = of;
  c.source = view();
  c.scales = scales();
  return c;
}

// ----------------------------------------------------------------------------- the run

struct PipelineRun::Conclusion {
  Summary s;
  double scale = 1.0;  ///< of the source the conclusion works on, over the original's
  std::unique_ptr<ScaledSource> source;  ///< free scale: the source at `scale`
  RefineContext all;                     ///< every landmark of that source
  Hypothesis best;
  Refinement fin;
  int iterations = 0;  ///< of the refinements before the final one
  /// With the scale free: the 7x7 covariance the scale's standard deviation comes from.
  std::optional<PoseCovariance> scale_covariance;
  /// The estimator's covariance came from end_pass (resample_covariance may raise it), and
  /// whether it has been.
  bool resamplable = false;
  bool resampled = false;
};

PipelineRun::PipelineRun(const Pipeline& pipeline, const SourceView& source,
                         const PreparedTarget& target, const PipelineRequest& request)
    : pipeline_(pipeline),
      settings_(pipeline.settings()),
      source_(source),
      target_(target),
      request_(request),
      start_(std::chrono::steady_clock::now()),
      guess_(request.initial_guess.value_or(Isometry3::Identity())) {}

PipelineRun::~PipelineRun() = default;

void PipelineRun::validate() const {
  if (source_.positions == nullptr || source_.positions->empty()) {
    throw InvalidArgument("registration: the source has no landmarks");
  }
  if (target_.size() == 0) throw InvalidArgument("registration: the target has no landmarks");
  const Points3& sp = *source_.positions;
  // The supported range (core/supported_range.hpp; align() of presets.hpp leaves such
  // landmarks out).
  for (const auto& [side, points] :
       {std::pair<const char*, const Points3*>{"source", &sp}, {"target", &target_.points()}}) {
    for (std::size_t i = 0; i < points->size(); ++i) {
      if (!within_supported_range((*points)[i])) {
        throw InvalidArgument(std::string("registration: ") + side + " landmark " +
                              std::to_string(i) + " is not finite or beyond " +
                              message_number(kMaxCoordinateM) + " m");
      }
    }
  }
  if (source_.has_covariances() && source_.covariances_m2->size() != sp.size()) {
    throw InvalidArgument("registration: " + std::to_string(source_.covariances_m2->size()) +
                          " source covariances for " + std::to_string(sp.size()) + " landmarks");
  }
  const PipelineSpec& spec = pipeline_.spec();
  std::string why;
  if (request_.prior && !request_.prior->is_valid(&why)) throw InvalidArgument(why);
  if (request_.prior && !pipeline_.initialiser().uses_prior()) {
    throw InvalidArgument("prior sigma: the initialiser '" + spec.initialiser + "' of '" +
                          spec.name + "' uses no prior");
  }
  if (request_.initial_guess && !is_finite(*request_.initial_guess)) {
    throw InvalidArgument("initial guess: not finite");
  }
  if (request_.initial_guess) {
    check_supported_translation("initial guess", request_.initial_guess->translation());
  }
  if (!request_.free_scale) return;
  const Estimator& e = pipeline_.estimator();
  if (e.degrees_of_freedom() != 6 || !e.estimates_scale()) {
    throw InvalidArgument("scale free: the estimator '" + spec.estimator + "' of '" + spec.name +
                          "' estimates " + std::to_string(e.degrees_of_freedom()) +
                          " degrees of freedom without the scale; a free scale needs a 6-DoF "
                          "estimator that estimates it");
  }
  if (sp.size() < 3 || target_.size() < 3) {
    throw InvalidArgument("scale free: fewer than 3 landmarks in a map");
  }
  if (request_.initial_scale &&
      (!std::isfinite(*request_.initial_scale) || !(*request_.initial_scale > 0.0))) {
    throw InvalidArgument("initial scale " + message_number(*request_.initial_scale) +
                          ": expected finite and > 0");
  }
}

bool PipelineRun::begin_search(double factor) {
  const std::vector<Mat3>* target_cov =
      target_.has_covariances() ? &target_.covariances_m2() : nullptr;
  const bool first = request_.free_scale && !scale_search_;
  if (first) {
    // The initial scale from the data: the spacings of the source as given and of the target.
    const ScaleSearchOptions o = scale_search_options(settings_);
    const DataScales a = estimate_data_scales(*source_.positions, source_.covariances_m2);
    const DataScales b = estimate_data_scales(target_.points(), target_cov, 4096, &target_.tree());
    scale_search_.emplace(o, request_.initial_scale.value_or(initial_scale_from_spacing(
                                 a.spacing_m, b.spacing_m, o.initial_min, o.initial_max)));
  }
  // Twice when the first search of a free scale measures the scale (ScaleSearch::
  // set_measured): the source again at the measured initial scale.
  std::vector<Isometry3> measured_poses;  // the measurement's, at the measured scale
  for (bool measure = first && scale_search_->measure_steps() > 0;; measure = false) {
    Summary& s = base_;
    s = Summary{};
    s.preset = pipeline_.spec().name;
    s.stages = pipeline_.spec();
    for (const SettingRow& row : settings_.table()) {
      s.settings.emplace_back(row.key, row.text(settings_.value(row.key)));
    }
    s.registration.T_target_source = guess_;
    search_source_.reset();
    if (scale_search_) {
      search_source_ = std::make_unique<ScaledSource>(source_, nullptr, true,
                                                      scale_search_->initial_scale() * factor);
    }
    const SourceView src = search_source_ ? search_source_->view() : source_;
    if (pipeline_.needs_scales()) {
      if (src.size() < 3 || target_.size() < 3) return false;
      Scales scales;
      scales.source = estimate_data_scales(*src.positions, src.covariances_m2);
      scales.target = estimate_data_scales(target_.points(), target_cov, 4096, &target_.tree());
      const double floor_setting = settings_.real("scales.floor_m");
      scales.floor_m = floor_setting > 0.0 ? floor_setting
                                           : std::max(scales.source.floor_m, scales.target.floor_m);
      scales.evidence_spacings = settings_.real("scales.evidence_spacings");
      scales.evidence_typical_sigmas = settings_.real("scales.evidence_typical_sigmas");
      const Vec3 default_up = stages::unit_vector(settings_, "scales.default_up");
      scales.up_source = src.up.value_or(default_up).normalized();
      scales.up_target = target_.up_axis().value_or(default_up).normalized();
      s.scales = scales;
    }
    RefineContext all;
    all.source = src;
    all.target = &target_;
    all.init = &s.initialisation;
    all.scales = s.scales ? &*s.scales : nullptr;
    InitialiserContext ic;
    ic.source = src;
    ic.target = &target_;
    ic.scales = all.scales;
    ic.initial_guess = request_.initial_guess;
    if (request_.prior) {
      ic.prior_sigma_deg_m =
          std::make_pair(request_.prior->rotation_deg, request_.prior->translation_m);
    }
    ic.pipeline = &pipeline_;
    ic.refine_context = &all;
    ic.pass = pass_;
    ic.checking = checking_;
    ic.free_scale = request_.free_scale;
    if (measure) {
      std::optional<ScaleMeasurement> m = pipeline_.initialiser().measure_scale(
          ic, scale_search_->measure_steps(), scale_search_->rung_ratio(),
          scale_search_->measure_margin());
      if (m && m->decisive) {
        scale_search_->set_measured(m->factor);
        if (factor == 1.0) measured_poses = std::move(m->poses);
        continue;
      }
      // Not decisive: the cliques still say which of the scales the searches go to to try
      // first; the first search then starts there.
      if (m && scale_search_->set_evidence(std::move(m->cliques))) continue;
    }
    ic.measured_poses = measured_poses;
    hypotheses_ = pipeline_.initialiser().propose(ic, &s.initialisation);
    if (hypotheses_.empty()) {
      if (!s.initialisation.declined.empty()) return false;  // unanswered(): not trusted
      throw Error("initialiser '" + pipeline_.spec().initialiser + "' proposed nothing");
    }
    if (keep_ && factor == keep_factor_) {
      Hypothesis kept = hypotheses_.front();
      kept.T_target_source = *keep_;
      kept.search_score = 0.0;
      kept.origin = "previous pass";
      kept.rival_only = false;
      hypotheses_.push_back(kept);
    }
    return true;
  }
}

Summary PipelineRun::unanswered() const {
  Summary s = base_;
  s.registration.termination = TerminationReason::kNoCorrespondences;
  s.verdict.reason = s.initialisation.declined.empty() ? "fewer than 3 landmarks in a map"
                                                       : s.initialisation.declined;
  add_caveats(&s);
  s.registration.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  s.total_time_s = s.registration.wall_time_s;
  return s;
}

Summary PipelineRun::conclude(double rung, bool may_defer) {
  // On the heap: the conclusion's contexts point into it, and it may be kept (provisional_).
  provisional_.reset();
  before_verdict_.reset();
  auto kept = std::make_unique<Conclusion>();
  Conclusion& c = *kept;
  c.s = base_;
  c.all.target = &target_;
  c.all.init = &c.s.initialisation;
  c.all.source = source_;
  c.all.scales = c.s.scales ? &*c.s.scales : nullptr;
  c.best = hypotheses_.front();
  if (pipeline_.scorer() != nullptr) {
    c.s.hypotheses = score_hypotheses(rung);
    for (const RefinedHypothesis& r : c.s.hypotheses) c.iterations += r.iterations;
    // A strict prior window: the best hypothesis that may be the answer goes first; the rivals
    // that scored higher follow it, and the trust judge weighs them (ambiguity above 1).
    const auto answer =
        std::find_if(c.s.hypotheses.begin(), c.s.hypotheses.end(),
                     [](const RefinedHypothesis& h) { return !h.start.rival_only; });
    if (answer != c.s.hypotheses.end()) {
      std::rotate(c.s.hypotheses.begin(), answer, answer + 1);
    }
    c.best = c.s.hypotheses.front().start;
    c.best.T_target_source = c.s.hypotheses.front().T_refined;
  }
  if (search_source_) {
    // The conclusion's source: the search's at the rung, its scales with it.
    c.source = scaled_search_source(rung);
    c.scale = search_source_->scale() * rung;
    if (c.s.scales) c.s.scales = *c.source->scales();
    c.all = c.source->context(c.all);
    c.all.scales = c.s.scales ? &*c.s.scales : nullptr;
  }
  refine_best(&c);
  // Scored on every landmark, the rivals are compared with the answer itself, which was refined
  // there (with the scale free, refine_scale does so). Measured: on a real desk pair with a
  // right prior the answer's own hypothesis, refined on the samples, put a rival at 70.1%
  // where the answer puts it at 69.2% (docs/accuracy.md, "Refined on samples, scored on every
  // landmark").
  if (!c.source) score_answer(&c, true);
  end_pass(&c);
  if (may_defer && first_pass()) {
    // The resampling (several refinements on every landmark) only where this conclusion may be
    // the result: not where the next pass replaces it whatever the resampling would say.
    auto before = std::make_unique<Summary>(c.s);
    judge(&c, false);
    if (deeper_either_way(c.s)) {
      Summary out = c.s;
      provisional_ = std::move(kept);
      before_verdict_ = std::move(before);
      return out;
    }
    c.s = std::move(*before);
  }
  judge(&c);
  return std::move(c.s);
}

bool PipelineRun::goes_deeper(const Summary& first) const {
  if (!first_pass()) return false;
  const Verdict& v = first.verdict;
  if (v.trustworthy) return prior_unconfirmed() || v.rivals_needed;
  return !v.trusted_but_for_prior_window && deeper_if_untrusted() &&
         !(deeper_needs_evidence() && v.no_evidence);
}

bool PipelineRun::deeper_either_way(const Summary& first) const {
  // Untrusted without the resampling: untrusted with it, for the same reason or an earlier one
  // (it runs in the verdict's last test and only raises the covariance), and no
  // trusted_but_for_prior_window either way. Trusted without it: with it, trusted (the same
  // answer to goes_deeper) or refused as too uncertain (no evidence is missing from a trusted
  // answer), which goes deeper when the search goes deeper after an untrusted answer.
  if (!goes_deeper(first)) return false;
  return !first.verdict.trustworthy || deeper_if_untrusted();
}

Summary PipelineRun::settle(Summary concluded) {
  if (!provisional_) return concluded;
  Conclusion& c = *provisional_;
  c.s = std::move(*before_verdict_);
  judge(&c);
  Summary out = std::move(c.s);
  provisional_.reset();
  before_verdict_.reset();
  return out;
}

std::unique_ptr<ScaledSource> PipelineRun::scaled_search_source(double factor) const {
  return std::make_unique<ScaledSource>(search_source_->view(),
                                        base_.scales ? &*base_.scales : nullptr,
                                        floor_is_a_setting(settings_), factor);
}

std::vector<RefinedHypothesis> PipelineRun::score_hypotheses(double rung) const {
  // Every hypothesis refined on the scorer's samples at the rung: the samples' positions times
  // the rung (covariances as they are, so that no rung's gate is wider than another's), each
  // pose moved to keep the source centre where the search put it; one per thread, each in its
  // own slot.
  // Each is then scored on the scorer's scoring samples (every landmark, by default): a pose
  // refined on a sample fits it, and the rivals' shares are measured where none was fitted more
  // than the rest.
  const Scorer& scorer = *pipeline_.scorer();
  const SourceView src = search_source_ ? search_source_->view() : source_;
  OwnedPart part = part_of(src, scorer.samples(src.size()));
  OwnedPart scoring_part = part_of(src, scorer.scoring_samples(src.size()));
  std::optional<Scales> scales = base_.scales;
  std::vector<Hypothesis> tried = hypotheses_;
  if (rung != 1.0) {
    for (Vec3& p : part.positions) p *= rung;
    for (Vec3& p : scoring_part.positions) p *= rung;
    if (scales) {
      DataScales& d = scales->source;
      d.centre_m *= rung;
      d.radius_m *= rung;
      d.spacing_m *= rung;
    }
    const Vec3 centre = base_.scales ? base_.scales->source.centre_m : Vec3::Zero();
    for (Hypothesis& h : tried) {
      h.scale_factor = rung;
      h.T_target_source.translation() += (1.0 - rung) * (h.T_target_source.linear() * centre);
    }
  }
  RefineContext context;
  context.source = part.view(src);
  context.target = &target_;
  context.scales = scales ? &*scales : nullptr;
  context.init = &base_.initialisation;
  RefineContext scoring = context;
  scoring.source = scoring_part.view(src);
  std::vector<RefinedHypothesis> refined(tried.size());
  // Refines `from` with a sharp gate (zero pose uncertainty) on the landmarks of `on`, scores
  // it on the scoring samples, and keeps that refinement in *out when it scores higher (true).
  const auto refine_sharply = [&](const RefineContext& on, Hypothesis from,
                                  RefinedHypothesis* out) {
    from.start_sigma_m = 0.0;
    from.start_sigma_rad = 0.0;
    const Refinement again = pipeline_.refine(on, from, Phase::kHypothesis);
    const double score = scorer.score(scoring, pipeline_, again.T);
    out->iterations += again.iterations;
    if (!(score > out->score)) return false;
    out->T_refined = again.T;
    out->termination = again.termination;
    out->score = score;
    return true;
  };
  // Refines `h` again from its start with a sharp gate, kept when it scores higher.
  const auto restart_sharp = [&](const Hypothesis& h, RefinedHypothesis* out) {
    if (refine_sharply(context, h, out)) out->sharp_restart = true;
  };
  const auto widened = [](const Hypothesis& h) {
    return h.start_sigma_m > 0.0 || h.start_sigma_rad > 0.0;
  };
  FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(tried.size()); ++i) {
    error.capture([&] {
      const Hypothesis& h = tried[static_cast<std::size_t>(i)];
      const Refinement r = pipeline_.refine(context, h, Phase::kHypothesis);
      RefinedHypothesis& out = refined[static_cast<std::size_t>(i)];
      out.start = h;
      out.T_refined = r.T;
      out.iterations = r.iterations;
      out.termination = r.termination;
      out.score = scorer.score(scoring, pipeline_, r.T);
      // The user's guess is never traded for a pose the score rates below it. A gate widened by
      // the start's pose uncertainty lets more landmarks pair and may carry the pose there
      // (measured: from the exact truth of a simulated street with a prior of 2 deg / 1 m, the
      // gate drifted one storey up the facades, gated score 282 -> 153; KITTI windows from
      // their truth at 4.2 deg / 1.5 m slid 1.9 m). Such a refinement of the guess starts again
      // from the guess with a sharp gate, and the better score wins.
      if (h.origin == "guess" && widened(h) &&
          out.score < scorer.score(scoring, pipeline_, h.T_target_source)) {
        restart_sharp(h, &out);
      }
    });
  }
  error.rethrow();
  // A search's hypothesis that lost to its own start, the same way (docs/accuracy.md, "A
  // hypothesis that loses to its start"): its start is coarse by design, so only where the
  // start could matter, scoring at least Scorer::sharp_restart_share of the best refined
  // hypothesis (a rival within the alias margin, or the answer). Restarting every such
  // hypothesis found stronger rivals that refused right answers on a real KITTI pair and on
  // roads, and cost a third more time. Whether it lost is asked on the samples it was refined
  // on (cheap); its start's share on the scoring samples, as the scores it is compared with.
  // After every hypothesis is refined, so that the best is the same for any thread count.
  if (const double share = scorer.sharp_restart_share(); share > 0.0) {
    double best = 0.0;
    for (const RefinedHypothesis& r : refined) best = std::max(best, r.score);
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(tried.size()); ++i) {
      error.capture([&] {
        const Hypothesis& h = tried[static_cast<std::size_t>(i)];
        RefinedHypothesis& out = refined[static_cast<std::size_t>(i)];
        if (h.origin == "guess" || !widened(h)) return;
        if (!(scorer.score(context, pipeline_, out.T_refined) <
              scorer.score(context, pipeline_, h.T_target_source))) {
          return;
        }
        if (scorer.score(scoring, pipeline_, h.T_target_source) < share * best) return;
        restart_sharp(h, &out);
      });
    }
    error.rethrow();
  }
  // The contenders refined again (Scorer::contenders; docs/accuracy.md, "Contenders refined
  // again"): a pose refined on the samples can stop short where they hold too few of the
  // overlap's landmarks. Measured on a held-out street (seed 79, 3,000 landmarks): a hypothesis
  // 0.27 deg / 0.87 m from the truth stopped there at 186, below a slide 40 m along the street
  // at 187; refined again on every landmark it reaches the truth at 341. In every search but a
  // first pass that a deeper one may follow (first_pass(): the complete search, with or without
  // a first pass before it, a check, a prior's search): in the first pass the contenders'
  // higher scores made rivals of them, and trusted answers paid for the deeper pass without a
  // different answer (a simulated road: 0.86 -> 2.15 s).
  if (!first_pass() && scorer.contenders() > 0) {
    std::vector<std::size_t> order(refined.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return refined[a].score > refined[b].score;
    });
    const double floor = order.empty() ? 0.0 : scorer.contender_share() * refined[order[0]].score;
    std::vector<std::size_t> chosen;
    for (std::size_t i : order) {
      if (chosen.size() == scorer.contenders() || !(refined[i].score >= floor)) break;
      chosen.push_back(i);
    }
    OwnedPart contender_part = part_of(src, scorer.contender_samples(src.size()));
    if (rung != 1.0) {
      for (Vec3& p : contender_part.positions) p *= rung;  // as the samples above
    }
    RefineContext contender = context;
    contender.source = contender_part.view(src);
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chosen.size()); ++c) {
      error.capture([&] {
        RefinedHypothesis& out = refined[chosen[static_cast<std::size_t>(c)]];
        Hypothesis from = out.start;
        from.T_target_source = out.T_refined;
        if (refine_sharply(contender, from, &out)) out.refined_again = true;
      });
    }
    error.rethrow();
  }
  std::stable_sort(
      refined.begin(), refined.end(),
      [](const RefinedHypothesis& a, const RefinedHypothesis& b) { return a.score > b.score; });
  return refined;
}

void PipelineRun::refine_best(Conclusion* c) const {
  // The best on every landmark, rigid; then, with the scale free, in 7 DoF from there.
  const int history = request_.record_history ? (request_.history_scores ? 2 : 1) : 0;
  const bool keep = pipeline_.schedule().end_pass() == Schedule::EndPass::kLastStep;
  // One matcher state for PCL's fitness score at the guess, the refinement and the score at
  // the estimate: the refinement's first pairs and the last score come from warm caches
  // (bit-identical to fresh searches; docs/performance.md).
  const Matcher& m = pipeline_.matcher();
  std::unique_ptr<StageState> state = m.begin(c->all);
  const double range = settings_.real("fitness.max_range_m");
  const double initial_score_m2 = m.fitness(c->all, state.get(), guess_, range).mean_sq_m2;
  c->fin = pipeline_.refine(c->all, c->best, Phase::kFinal, keep, history, state.get());
  if (c->source) {
    refine_scale(c);
    state = m.begin(c->all);  // the source may be another (rescaled)
  }
  RegistrationResult& reg = c->s.registration;
  const Refinement& fin = c->fin;
  reg.T_target_source = fin.T;
  reg.termination = fin.termination;
  reg.converged = fin.termination == TerminationReason::kTransform ||
                  fin.termination == TerminationReason::kAbsoluteMse ||
                  fin.termination == TerminationReason::kRelativeMse;
  reg.iterations = c->iterations + fin.iterations;
  reg.num_correspondences = fin.num_pairs;
  reg.history = fin.history;
  reg.initial_score_m2 = initial_score_m2;
  reg.final_score_m2 = m.fitness(c->all, state.get(), fin.T, range).mean_sq_m2;
}

void PipelineRun::refine_scale(Conclusion* c) const {
  // The 7-DoF refinement from the rigid one, kept when the scorer scores the similarity at
  // least as well on every landmark (without a scorer: always): the score is what the verdict
  // measures, so a similarity never ends below the rigid answer it started from.
  const Scorer* scorer = pipeline_.scorer();
  Hypothesis from = c->best;
  from.T_target_source = c->fin.T;
  RefineContext free = c->all;
  free.free_scale = true;
  const int history = request_.record_history ? (request_.history_scores ? 2 : 1) : 0;
  const bool keep = pipeline_.schedule().end_pass() == Schedule::EndPass::kLastStep;
  Refinement sim = pipeline_.refine(free, from, Phase::kFinal, keep, history);
  const bool ended = sim.termination != TerminationReason::kNoCorrespondences &&
                     sim.termination != TerminationReason::kDegenerate;
  c->s.scale.free = true;
  if (!ended || !(sim.scale > 0.0) || !std::isfinite(sim.scale)) return;
  std::unique_ptr<ScaledSource> at = scaled_search_source(c->source->scale() * sim.scale);
  RefineContext all_sim = at->context(c->all);
  if (scorer != nullptr &&
      scorer->score(all_sim, pipeline_, sim.T) < scorer->score(c->all, pipeline_, c->fin.T)) {
    return;
  }
  c->iterations += c->fin.iterations;
  c->fin = std::move(sim);
  c->scale *= c->fin.scale;
  c->source = std::move(at);
  if (c->s.scales) c->s.scales = *c->source->scales();
  c->all = c->source->context(c->all);
  c->all.scales = c->s.scales ? &*c->s.scales : nullptr;
  ++c->s.scale.rounds;
  // The best hypothesis scored again at the refined scale, on the same landmarks as the others:
  // its rung may be 6% off, and the trust judge's margin to the rivals must not count that
  // against it.
  score_answer(c, false);
}

void PipelineRun::score_answer(Conclusion* c, bool every_landmark_only) const {
  const Scorer* scorer = pipeline_.scorer();
  if (scorer == nullptr || c->s.hypotheses.empty()) return;
  const std::size_t n = c->all.source.size();
  const std::vector<std::uint32_t> at = scorer->scoring_samples(n);
  double at_estimate = 0.0;
  if (at.size() == n) {
    at_estimate = scorer->score(c->all, pipeline_, c->fin.T);  // every landmark: no copy
  } else {
    if (every_landmark_only) return;
    const OwnedPart part = part_of(c->all.source, at);
    RefineContext sub = c->all;
    sub.source = part.view(c->all.source);
    at_estimate = scorer->score(sub, pipeline_, c->fin.T);
  }
  RefinedHypothesis& front = c->s.hypotheses.front();
  if (at_estimate > front.score) {
    front.score = at_estimate;
    front.T_refined = c->fin.T;
  }
}

Pairs PipelineRun::pairs_at_estimate(const RefineContext& all, const Refinement& fin,
                                     LoopState* loop) const {
  *loop = fin.loop;
  loop->final_pass = true;
  loop->free_scale = all.free_scale;
  loop->sigma.pivot_m =
      fin.T * (all.scales != nullptr ? all.scales->source.centre_m : Vec3::Zero());
  std::unique_ptr<StageState> state = pipeline_.matcher().begin(all);
  Pairs pairs;
  pipeline_.matcher().match(all, state.get(), fin.T, *loop, &pairs);
  for (const auto& r : pipeline_.rejectors()) r->reject(all, loop, &pairs);
  if (pairs.size() > 0) {
    loop->distribution_step = pipeline_.estimator().distribution_step(*loop);
    pipeline_.kernel().weigh(all, *loop, pairs, fin.T, Isometry3::Identity(), &pairs.weights);
  }
  return pairs;
}

void PipelineRun::end_pass(Conclusion* c) const {
  Summary& s = c->s;
  const Refinement& fin = c->fin;
  const Estimator& estimator = pipeline_.estimator();
  RefineContext all = c->all;
  all.free_scale = c->source != nullptr;
  Pose estimate;
  estimate.T_target_source = fin.T;
  const Schedule::EndPass end = pipeline_.schedule().end_pass();
  if (end == Schedule::EndPass::kAtEstimate) {
    LoopState loop;
    const Pairs pairs = pairs_at_estimate(all, fin, &loop);
    EstimateDiagnostics& d = s.at_estimate;
    d.computed = true;
    d.num_pairs = pairs.size();
    d.max_distance_m = loop.max_distance_m;
    d.overlap_ratio = fin.loop.overlap_ratio;
    d.inlier_ratio = static_cast<double>(pairs.size()) / static_cast<double>(all.source.size());
    if (pairs.size() > 0) {
      double wsum = 0.0, wr2 = 0.0;
      for (std::size_t i = 0; i < pairs.size(); ++i) {
        const double w = pairs.weights.empty() ? 1.0 : pairs.weights[i];
        const double d2 =
            pairs.kind == Pairs::Kind::kPoints
                ? pairs.points[i].distance_sq_m2
                : (target_.points()[pairs.gated[i].target_index] - pairs.gated[i].moved_source_m)
                      .squaredNorm();
        wsum += w;
        wr2 += w * d2;
      }
      d.inlier_rms_m = wsum > 0.0 ? std::sqrt(wr2 / wsum) : 0.0;
      if (wsum > 0.0) {
        s.estimator_covariance =
            estimator.covariance(all, pipeline_, loop, pairs, estimate, nullptr);
        c->resamplable = true;
      }
    }
  } else if (end == Schedule::EndPass::kLastStep && fin.has_step && fin.last_step.ok) {
    LoopState loop = fin.loop;
    loop.free_scale = all.free_scale;
    s.estimator_covariance =
        estimator.covariance(all, pipeline_, loop, fin.last_pairs, estimate, &fin.last_step);
    c->resamplable = true;
  } else if (all.free_scale) {
    // A pipeline that reports no covariance still reports its scale's standard deviation: the
    // estimator's covariance of the pairs at the estimate, for the scale alone.
    LoopState loop;
    const Pairs pairs = pairs_at_estimate(all, fin, &loop);
    if (pairs.size() > 0) {
      c->scale_covariance = estimator.covariance(all, pipeline_, loop, pairs, estimate, nullptr);
    }
  }
  s.covariance = s.estimator_covariance;
  if (s.estimator_covariance.has_scale) c->scale_covariance = s.estimator_covariance;
  // The alignment's time; the verdict's is in total_time_s.
  s.registration.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void PipelineRun::resample_covariance(Conclusion* c) const {
  if (!c->resamplable || c->resampled) return;
  c->resampled = true;
  Summary& s = c->s;
  RefineContext all = c->all;
  all.free_scale = c->source != nullptr;
  Pose estimate;
  estimate.T_target_source = c->fin.T;
  s.estimator_covariance = pipeline_.estimator().resampled_covariance(
      all, pipeline_, estimate, s.estimator_covariance, &s.num_half_samples);
  s.covariance = s.estimator_covariance;
  if (s.estimator_covariance.has_scale) c->scale_covariance = s.estimator_covariance;
}

void PipelineRun::judge(Conclusion* c, bool resample) const {
  Summary& s = c->s;
  if (const TrustJudge* judge = pipeline_.trust()) {
    JudgeContext jc;
    jc.context = c->all;
    jc.pipeline = &pipeline_;
    jc.final = &c->fin;
    jc.hypotheses = &s.hypotheses;
    jc.init = &s.initialisation;
    jc.covariance = &s.estimator_covariance;
    if (resample) {
      jc.resampled_covariance = [this, c]() -> const PoseCovariance& {
        resample_covariance(c);
        return c->s.estimator_covariance;
      };
    }
    if (request_.prior && request_.initial_guess) {
      jc.initial_guess = request_.initial_guess;
      jc.prior_sigma_deg_m =
          std::make_pair(request_.prior->rotation_deg, request_.prior->translation_m);
    }
    s.verdict = judge->judge(jc);
    // A trusted answer carries the resampled covariance, whichever judge trusted it.
    if (resample && s.verdict.trustworthy) resample_covariance(c);
    if (s.verdict.covariance) s.covariance = *s.verdict.covariance;
    check_prior_window(c);
  } else if (resample) {
    resample_covariance(c);
  }
  if (c->source) {
    ScaleEstimate& e = s.scale;
    e.free = true;
    e.scale = c->scale;
    e.initial_scale = scale_search_->initial_scale();
    e.measured_factor = scale_search_->measured_factor();
    e.lead_factor = scale_search_->lead_factor();
    if (c->scale_covariance && c->scale_covariance->valid && c->scale_covariance->has_scale) {
      Mat7 c7 = c->scale_covariance->covariance_7x7;
      if (s.verdict.covariance_scale > 1.0) c7 *= s.verdict.covariance_scale;
      e.covariance_7x7 = c7;
      e.scale_sd = e.scale * std::sqrt(std::max(0.0, c7(6, 6)));
    }
  }
  add_caveats(&s);
}

void PipelineRun::check_prior_window(Conclusion* c) const {
  // A prior is a hint (issue 41): an answer outside its window (3 sigma in rotation, and for the
  // source centre's image 3 (sigma_t + sigma_r x its distance from the target origin), widened
  // by the search's resolution) is not trusted, and the verdict says where the maps put it.
  if (!request_.prior || !request_.initial_guess) return;
  Summary& s = c->s;
  const Isometry3& guess = *request_.initial_guess;
  const Isometry3& answer = s.registration.T_target_source;
  const Vec3 centre = s.scales ? s.scales->source.centre_m : Vec3::Zero();
  const PoseWindow window =
      PoseWindow::of_prior(guess, request_.prior->rotation_deg, request_.prior->translation_m);
  const PoseWindow::Check w =
      window.check(answer, centre, s.initialisation.resolution_m, s.initialisation.resolution_rad);
  if (w.inside()) return;
  const double rot_rad = w.rotation_rad, moved_m = w.moved_m;
  const double max_rot = w.max_rotation_rad, max_moved = w.max_moved_m;
  s.verdict.outside_prior_window = true;
  s.verdict.trusted_but_for_prior_window = s.verdict.trustworthy;
  s.verdict.trustworthy = false;
  const std::string where = message_number(moved_m) + " m / " +
                            message_number(rot_rad * 180.0 / kPi) + " deg from the guess";
  const std::string bounds =
      message_number(max_moved) + " m / " + message_number(max_rot * 180.0 / kPi) + " deg";
  s.verdict.reason = "the maps prefer a pose outside the prior's window: " + where +
                     " (the window: " + bounds + ")" +
                     (s.verdict.reason == "ok" ? "" : "; " + s.verdict.reason);
}

void PipelineRun::add_caveats(Summary* summary) const {
  // The caveats every verdict carries: a confidence that is 0 everywhere (Eqs. 2-3 on a target
  // without observations) never picks a neighbour (Eq. 6) and zeroes every pair's weight, so
  // nothing was aligned; landmarks left out; covariances assumed.
  Summary& s = *summary;
  for (WeightKind kind : pipeline_.confidences()) {
    const std::vector<double>& w = target_.weights(kind);
    if (!w.empty() && std::all_of(w.begin(), w.end(), [](double x) { return x == 0.0; })) {
      s.verdict.trustworthy = false;
      s.verdict.reason = "every target landmark has " + to_string(kind) +
                         " weight 0 (it has no observations: a point cloud), so the strategy "
                         "weighs every pair by 0 (method.md Eqs. 2-3, 6): nothing was "
                         "aligned; use base, covariance or adaptive";
      break;
    }
  }
  s.source_left_out = request_.source_left_out;
  s.target_left_out = request_.target_left_out;
  std::string note = left_out_message(request_.source_left_out, request_.target_left_out);
  if (request_.covariances_assumed && pipeline_.uses_covariances()) {
    s.covariances_assumed = true;
    note = (note.empty() ? "" : note + "; ") +
           "covariances assumed from the landmark spacing (isotropic, half the median distance "
           "to the 6 nearest landmarks: the map stores none), so the covariance weights and "
           "gates measure agreement with that assumption";
  }
  if (!note.empty()) s.verdict.reason += "; " + note;
}

void PipelineRun::add_scale_poses(const Summary& concluded, std::vector<ScalePose>* poses) {
  const Verdict& v = concluded.verdict;
  poses->push_back({concluded.registration.T_target_source, concluded.scale.scale, v.score});
  if (v.rival_T_target_source) {
    poses->push_back({*v.rival_T_target_source, concluded.scale.scale, v.ambiguity * v.score});
  }
}

void PipelineRun::weigh_earlier_scales(Summary* later,
                                       const std::vector<ScalePose>& earlier) const {
  const char* keys[] = {"trust.max_ambiguity", "trust.alias_ambiguity", "trust.alias_nis_ratio",
                        "trust.distinct_cells"};
  for (const char* k : keys) {
    if (!settings_.has(k)) return;
  }
  Verdict& v = later->verdict;
  if (!v.trustworthy || earlier.empty() || source_.size() == 0 || !(v.score > 0.0)) return;
  const double max_ambiguity = settings_.real("trust.max_ambiguity");
  const double alias_ambiguity = settings_.real("trust.alias_ambiguity");
  const bool aliased_residuals =
      v.mean_nis > settings_.real("trust.alias_nis_ratio") * v.expected_nis;
  const double distinct_m =
      settings_.real("trust.distinct_cells") * later->initialisation.resolution_m;
  // The source's centre and radius in its own units; each pose maps them into the target.
  if (!source_scales_) {
    source_scales_ = estimate_data_scales(*source_.positions, source_.covariances_m2);
  }
  const DataScales& sc = *source_scales_;
  const Isometry3& T = later->registration.T_target_source;
  const Vec3 at_later = later->scale.scale * (T.linear() * sc.centre_m) + T.translation();
  for (const ScalePose& r : earlier) {
    const double share = r.score / v.score;
    if (!(share >= max_ambiguity || (share >= alias_ambiguity && aliased_residuals))) continue;
    // Apart at the source's radius: the centres, the turn and the difference in scale.
    const double apart_m = (r.scale * (r.T_target_source.linear() * sc.centre_m) +
                            r.T_target_source.translation() - at_later)
                               .norm();
    const double angle =
        Eigen::AngleAxisd(r.T_target_source.linear() * T.linear().transpose()).angle();
    const double spread_m =
        apart_m +
        (angle * later->scale.scale + std::abs(r.scale - later->scale.scale)) * sc.radius_m;
    if (spread_m <= distinct_m) continue;
    v.trustworthy = false;
    v.ambiguity = share;
    v.rival_T_target_source = r.T_target_source;
    v.rival_distance_m = apart_m;
    v.rival_angle_deg = angle * 180.0 / kPi;
    v.reason = "ambiguous: a pose an earlier scale (" + message_number(r.scale) + ") found, " +
               message_number(apart_m) + " m / " + message_number(v.rival_angle_deg) +
               " deg away, scores " + std::to_string(static_cast<int>(std::lround(100.0 * share))) +
               "% of the best";
    if (share < max_ambiguity) {
      v.reason += ", and the inliers' residuals exceed their covariances (mean NIS " +
                  message_number(v.mean_nis / v.expected_nis) + " times its expectation)";
    }
    return;
  }
}

Summary PipelineRun::finish(Summary s, int attempts, int searches) const {
  s.scale.attempts = attempts;
  s.scale.searches = searches;
  s.total_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  return s;
}

}  // namespace lmalign::detail
