// One run of a Pipeline (Pipeline::run, include/lmalign/registration/pipeline.hpp): its phases,
// each a short member function over one state. Internal to src/registration/.
//
//   validate        the inputs and the request (throws)
//   begin_search    the source at the search's initial scale (free scale), the data's scales,
//                   the initialiser's hypotheses (from its first pass; deepen() for the next)
//   conclude        at one place of the scale axis: the hypotheses refined on the scorer's
//                   samples and scored on its scoring samples, every landmark by default
//                   (score_hypotheses), the best refined on every landmark, in 7 DoF too when
//                   the scale is free (refine_best), the answer scored where the rivals were
//                   (score_answer), the covariance and the
//                   diagnostics (end_pass), the verdict with its caveats (judge; the
//                   covariance's costly resampling only where the verdict asks for it or
//                   trusts the answer, never for a pass the next one replaces whatever it
//                   says: resample_covariance, deeper_either_way, settle)
//   finish          the times
//
// Frames: T_target_source, p_target = T_target_source * (scale * p_source).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "lmalign/registration/pipeline.hpp"

namespace lmalign::detail {

/// True when the covariance floor is a setting (scales.floor_m > 0), not the data's.
bool floor_is_a_setting(const Settings& settings);

/// The landmarks `indices` of a view, copied out (a refinement on part of them).
struct OwnedPart {
  Points3 positions;
  std::vector<Mat3> covariances_m2;
  std::vector<Vec3> view_directions;
  SourceView view(const SourceView& of) const {
    return {&positions, &covariances_m2, of.up, &view_directions};
  }
};
OwnedPart part_of(const SourceView& source, const std::vector<std::uint32_t>& indices);

/// A source at a scale: its positions times the scale, its covariances times its square, and
/// the source's data scales (spacing, floor, radius, centre) with them; always recomputed from
/// the original, so that the same scale gives the same numbers however it was reached. Neither
/// copied nor moved: views point into it.
class ScaledSource {
 public:
  /// `scales`: the pipeline's scales at `scale` 1 (null when it reads none); `floor_fixed`: the
  /// covariance floor is a setting (else the larger of the two maps').
  ScaledSource(const SourceView& original, const Scales* scales, bool floor_fixed, double scale);
  ScaledSource(const ScaledSource&) = delete;
  ScaledSource& operator=(const ScaledSource&) = delete;

  void set_scale(double scale);
  double scale() const { return scale_; }
  /// (Viewing directions do not change with the scale: the original's.)
  SourceView view() const {
    return {&positions_, &covariances_, original_.up, original_.view_directions};
  }
  const Scales* scales() const { return scales_ ? &*scales_ : nullptr; }
  /// A context of every landmark of this source (the rest as `of`).
  RefineContext context(const RefineContext& of) const;

 private:
  SourceView original_;
  std::optional<Scales> original_scales_;
  bool floor_fixed_;
  double scale_ = 1.0;
  Points3 positions_;
  std::vector<Mat3> covariances_;
  std::optional<Scales> scales_;
};

class PipelineRun {
 public:
  PipelineRun(const Pipeline& pipeline, const SourceView& source, const PreparedTarget& target,
              const PipelineRequest& request);
  ~PipelineRun();

  /// Throws InvalidArgument as Pipeline::run documents.
  void validate() const;
  bool scale_free() const { return request_.free_scale; }
  const ScaleSearch& scale_search() const { return *scale_search_; }
  /// A search at `factor` times the data's initial scale (1 without a free scale): the source
  /// there, the scales, the hypotheses. False when a map has fewer than 3 landmarks for a
  /// pipeline that reads the scales, or when the initialiser declines to propose
  /// (InitialiserReport::declined); then unanswered() is the result.
  bool begin_search(double factor);
  /// True when the current search's hypotheses came from a pass with a deeper one after it
  /// (InitialiserReport::deeper_pass); deepen() makes every later search the next pass.
  bool first_pass() const { return base_.initialisation.deeper_pass; }
  /// InitialiserReport::prior_unconfirmed of the current search.
  bool prior_unconfirmed() const { return base_.initialisation.prior_unconfirmed; }
  /// InitialiserReport::deeper_if_untrusted of the current search.
  bool deeper_if_untrusted() const { return base_.initialisation.deeper_if_untrusted; }
  /// InitialiserReport::deeper_needs_evidence of the current search.
  bool deeper_needs_evidence() const { return base_.initialisation.deeper_needs_evidence; }
  /// The next pass; `keep`: a pose the next pass's hypotheses include ("previous pass": the
  /// previous pass's answer, so that the next one finds its rivals without losing it);
  /// `checking`: that answer was trusted, and the next pass checks it
  /// (InitialiserContext::checking); `keep_factor`: the search factor `keep` was found at (it
  /// joins the searches at that factor only).
  void deepen(std::optional<Isometry3> keep = std::nullopt, bool checking = false,
              double keep_factor = 1.0) {
    ++pass_;
    keep_ = keep;
    keep_factor_ = keep_factor;
    checking_ = checking;
  }
  /// Every later search is a first pass again (Pipeline::run: after the check of a free scale's
  /// answer at another scale, the first passes at the remaining scales).
  void restart_first_pass() {
    pass_ = 0;
    keep_.reset();
    checking_ = false;
  }
  /// The result without an answer (begin_search() false): not trusted, the pose the initial
  /// guess, the reason the initialiser's (InitialiserReport::declined) or too few landmarks.
  Summary unanswered() const;
  /// The hypotheses of the current search concluded at `rung` times its initial scale. With
  /// `may_defer` (Pipeline::run's passes, not the scale axis' rungs), a first pass's conclusion
  /// that goes deeper whatever the covariance's resampling says (deeper_either_way) is judged
  /// without the resampling and kept: the next pass's result replaces it, or settle() finishes
  /// it when that pass cannot begin. Either way the result is the one a conclusion with the
  /// resampling gives.
  Summary conclude(double rung, bool may_defer = false);
  /// Whether the run goes on to the next pass after `first`, the current search's conclusion
  /// (Pipeline::run, docs/accuracy.md "The first pass").
  bool goes_deeper(const Summary& first) const;
  /// The conclusion conclude() kept, judged with the covariance's resampling; the summary it
  /// returned when it kept none.
  Summary settle(Summary concluded);
  /// True when the last conclude() kept its conclusion (judged without the resampling).
  bool deferred() const { return provisional_ != nullptr; }
  /// The summary with the run's times and the scale search's counts.
  Summary finish(Summary s, int attempts, int searches) const;
  /// A free scale's earlier scales found rivals of a later answer (docs/scale.md, "Limits"): a
  /// trusted `later` is refused when an earlier scale's answer or best rival, at a distinct
  /// pose (apart by trust.distinct_cells of the search's resolution at the source's radius,
  /// counting the turn and the difference in scale), scores trust.max_ambiguity of it, or
  /// trust.alias_ambiguity with the residuals above their covariances (the gated judge's
  /// tests). No-op for an untrusted `later`, and for pipelines without those settings.
  /// A pose a concluded scale found, for weigh_earlier_scales(): its answer or its best rival.
  struct ScalePose {
    Isometry3 T_target_source;
    double scale = 1.0;
    double score = 0.0;  ///< gated score
  };
  /// The answer of `concluded` and its best rival (if any), appended to `poses`.
  static void add_scale_poses(const Summary& concluded, std::vector<ScalePose>* poses);
  void weigh_earlier_scales(Summary* later, const std::vector<ScalePose>& earlier) const;

 private:
  struct Conclusion;
  /// The search's source times `factor` (its scales with it).
  std::unique_ptr<ScaledSource> scaled_search_source(double factor) const;
  std::vector<RefinedHypothesis> score_hypotheses(double rung) const;
  void refine_best(Conclusion* c) const;
  void refine_scale(Conclusion* c) const;
  /// The answer (c->fin.T) scored on the scorer's scoring samples; it replaces the best
  /// hypothesis' pose and score when it scores higher, so that the trust judge measures each
  /// rival's share against the answer itself. `every_landmark_only`: only when the scoring
  /// samples are every landmark (then scored on c->all without a copy).
  void score_answer(Conclusion* c, bool every_landmark_only) const;
  /// The last level's pairs re-made at the estimate and weighted (*loop: their loop state).
  Pairs pairs_at_estimate(const RefineContext& all, const Refinement& fin, LoopState* loop) const;
  void end_pass(Conclusion* c) const;
  /// The estimator's covariance raised by its resampling (Estimator::resampled_covariance;
  /// several refinements): once, and only where a verdict asks for it or trusts the answer.
  void resample_covariance(Conclusion* c) const;
  /// The verdict; `resample`: the covariance's resampling where the verdict asks for it or trusts
  /// the answer (false: the estimator's covariance alone, for a conclusion the next pass replaces).
  void judge(Conclusion* c, bool resample = true) const;
  /// True when `first` goes deeper whether or not the covariance is resampled: the resampling
  /// only ever refuses a trusted answer as too uncertain, which goes deeper too when the
  /// current search goes deeper after an untrusted answer.
  bool deeper_either_way(const Summary& first) const;
  /// With a prior and a guess: an answer outside the prior's window is not trusted (issue 41).
  void check_prior_window(Conclusion* c) const;
  /// The verdict's caveats: a confidence 0 everywhere, landmarks left out, covariances assumed.
  void add_caveats(Summary* s) const;

  const Pipeline& pipeline_;
  const Settings& settings_;
  SourceView source_;
  const PreparedTarget& target_;
  const PipelineRequest& request_;
  std::chrono::steady_clock::time_point start_;
  Isometry3 guess_;
  std::optional<ScaleSearch> scale_search_;
  int pass_ = 0;
  std::optional<Isometry3> keep_;
  double keep_factor_ = 1.0;
  bool checking_ = false;
  /// conclude()'s conclusion judged without the resampling, with the summary as it was before
  /// the verdict (settle() judges it again); null when none is kept.
  std::unique_ptr<Conclusion> provisional_;
  std::unique_ptr<Summary> before_verdict_;
  /// The current search: its source (copied at its initial scale when the scale is free), the
  /// summary every conclusion starts from (preset, settings, scales, initialiser report), its
  /// hypotheses.
  std::unique_ptr<ScaledSource> search_source_;
  /// The source's centre and radius (its own units) for weigh_earlier_scales(), once.
  mutable std::optional<DataScales> source_scales_;
  Summary base_;
  std::vector<Hypothesis> hypotheses_;
};

}  // namespace lmalign::detail
