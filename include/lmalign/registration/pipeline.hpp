// The registration engine: one Pipeline, built at run time from one stage per seam
// (seams.hpp) and one table of settings (settings.hpp). Every named strategy is a preset of it
// (presets.hpp): the paper's ICP, lmalign's robust presets and the adaptive default.
//
//   scales        measured when a stage needs them (data_scales.hpp)
//   initialiser   hypotheses, each with the pose uncertainty its gate starts from
//   with a scorer each hypothesis is refined on the scorer's samples and scored on its scoring
//                 samples (every landmark by default); the best wins
//   refinement    per iteration: match -> reject -> (weigh -> estimate) x re-weightings ->
//                 schedule (level changes, termination), from the best hypothesis, every
//                 landmark
//   covariance    the estimator's, from the last step or from the pairs at the estimate
//   trust judge   from every refined hypothesis, their scores and the initialiser's report
//
// Hypotheses are refined in parallel, one per thread, each in its own slot; stages loop over
// landmarks with one slot each and sum serially. Results are identical for any thread count.
//
// Frames: T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/similarity.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/scale_search.hpp"
#include "lmalign/registration/seams.hpp"
#include "lmalign/registration/settings.hpp"

namespace lmalign {

/// A prior on the transform: standard deviations of the rotation (degrees, about any axis) and
/// of the translation (metres) of the initial guess, of the left perturbation about the target
/// origin (uncertainty.hpp). Both within the supported range of a standard deviation,
/// [1e-9, 1e15] (core/supported_range.hpp).
struct PriorSigma {
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  bool is_valid(std::string* why = nullptr) const;
};

/// Which stage fills each seam (registry names, stages/registry), and the settings that differ
/// from the stages' defaults (by key).
struct PipelineSpec {
  std::string name = "custom";
  std::string initialiser = "guess";
  std::string matcher = "nearest";
  std::vector<std::string> rejectors;
  std::string kernel = "none";
  std::string estimator = "umeyama";
  std::string schedule = "pcl";
  std::string scorer = "none";
  std::string trust = "none";
  std::vector<std::pair<std::string, SettingValue>> settings;
};

/// What one alignment is asked, beyond the pipeline.
struct PipelineRequest {
  /// The start (identity if none). An initialiser that searches adds it to its hypotheses, or
  /// with `prior` bounds its search around it.
  std::optional<Isometry3> initial_guess;
  std::optional<PriorSigma> prior;
  /// Per-iteration history of the final refinement (pairs, their mean squared distance), with
  /// the fitness score at every iteration when history_scores is set.
  bool record_history = false;
  bool history_scores = false;
  /// Estimate the scale too (Sim(3), registration/scale_search.hpp): the source is rescaled by
  /// an initial scale from the data (initial_scale_from_spacing), the initialiser searches on it
  /// (an initial guess and a prior apply to the rescaled source), the best hypothesis is refined
  /// on every landmark, then again in 7 DoF by the estimator (Umeyama with scale for point
  /// pairs, the 7-DoF point-to-distribution step for distribution pairs), kept when the
  /// scorer's score at the similarity is at least that of the rigid refinement. Without a
  /// trusted verdict the ScaleSearch concludes the hypotheses again at its rungs, then, unless
  /// the landmarks' correspondences measured the scale before the first search, searches
  /// again at other initial scales (settings scale.*). Needs a 6-DoF estimator that estimates
  /// the scale. False: rigid, as before (the scale stays exactly 1).
  bool free_scale = false;
  /// With free_scale: the initial scale (finite, > 0) instead of the one from the data.
  std::optional<double> initial_scale;
  /// What the judging phase adds to the verdict's reason (presets.hpp's align() fills them):
  /// landmarks of each side left out for being beyond the supported range (counted; the reason
  /// ends with left_out_message()), and whether either map's covariances are assumed (noted when
  /// the pipeline uses covariances).
  std::size_t source_left_out = 0;
  std::size_t target_left_out = 0;
  bool covariances_assumed = false;
};

/// The scale of a result (Sim(3); all defaults when the scale was fixed).
struct ScaleEstimate {
  bool free = false;  ///< estimated (else fixed at 1)
  /// Target units per source unit: p_target = scale * R * p_source + t.
  double scale = 1.0;
  /// Its standard deviation (target units per source unit; first order from the 7x7 covariance
  /// of log scale); NaN when fixed or not determined.
  double scale_sd = std::numeric_limits<double>::quiet_NaN();
  /// Where the search started: the initial scale from the data (target / source median
  /// landmark spacing, in [1/10, 10]) times the measured factor, if any.
  double initial_scale = 1.0;
  /// The factor the landmarks' correspondences measured on the spacings' scale before the first
  /// search (ScaleSearch::set_measured); NaN when none was measured (then the search went on
  /// at other initial scales while none was trusted).
  double measured_factor = std::numeric_limits<double>::quiet_NaN();
  /// When the measurement was not decisive: the factor, among the searches' scales, where its
  /// cliques were largest and the first search therefore started (ScaleSearch::set_evidence;
  /// initial_scale includes it); NaN when none moved it.
  double lead_factor = std::numeric_limits<double>::quiet_NaN();
  /// 7-DoF refinements kept (their score was at least the rigid refinement's), over every
  /// concluded scale.
  int rounds = 0;
  /// Rungs of the scale axis concluded (Pipeline::run: every hypothesis refined at the rung,
  /// the best on every landmark, the verdict), over every search.
  int attempts = 1;
  /// Searches run: the first, and the ScaleSearch's searches again at other initial scales when
  /// no rung of the first is trusted.
  int searches = 1;
  /// The 7x7 covariance of (rho [target units], phi [rad], log scale) as a left perturbation
  /// about the target origin: the estimator's 7-DoF covariance at the estimate (for the adaptive
  /// default the cluster-robust sandwich raised to the half-sample covariance, each half
  /// re-aligned with its own scale), times the verdict's covariance scale; nullopt when fixed or
  /// singular.
  std::optional<Mat7> covariance_7x7;
};

/// The diagnostics at the estimate after the last step (schedules that ask for them): the last
/// level's pairs there.
struct EstimateDiagnostics {
  bool computed = false;
  std::size_t num_pairs = 0;
  double inlier_ratio = 0.0;   ///< pairs kept / source landmarks
  double overlap_ratio = 1.0;  ///< the trim ratio used
  double max_distance_m = std::numeric_limits<double>::infinity();  ///< of the last level
  double inlier_rms_m = 0.0;  ///< weighted RMS distance of the pairs, metres
};

/// What an alignment returns (after Ceres' Solver::Summary).
struct Summary {
  std::string preset;
  /// The stages that ran, and the settings that differed from their defaults.
  PipelineSpec stages;
  /// Every setting of the pipeline, key and value as text (settings.hpp), in table order.
  std::vector<std::pair<std::string, std::string>> settings;
  /// The estimate, termination, iterations (every refinement's), pairs of the last iteration,
  /// PCL's fitness scores at the initial guess and at the estimate, the history, the wall time.
  RegistrationResult registration;
  InitialiserReport initialisation;
  /// Every refined hypothesis, by decreasing score (empty when there was no scoring).
  std::vector<RefinedHypothesis> hypotheses;
  /// The scales (when a stage needed them).
  std::optional<Scales> scales;
  EstimateDiagnostics at_estimate;
  /// The scale (free scale only; registration.T_target_source is then the rotation and
  /// translation of the similarity, similarity() the whole of it).
  ScaleEstimate scale;
  /// The estimator's covariance (raised to the half-sample covariance where that ran), and the
  /// halves that entered it.
  PoseCovariance estimator_covariance;
  std::size_t num_half_samples = 0;
  Verdict verdict;
  /// The covariance reported: the judge's own if it has one, else the estimator's.
  PoseCovariance covariance;
  /// Wall time of the whole call, the verdict included (registration.wall_time_s stops before
  /// the verdict), seconds.
  double total_time_s = 0.0;
  /// Landmarks of each side left out of the alignment for being beyond the supported range
  /// (core/supported_range.hpp; align() of presets.hpp leaves them out). When any were, the
  /// verdict's reason ends with "; " and left_out_message() (e.g. "ok; 1 source landmark beyond
  /// the supported range (|coordinate| > 1e+15 m) left out"), and the verdict is that of the
  /// alignment of the others.
  std::size_t source_left_out = 0;
  std::size_t target_left_out = 0;
  /// AlignRequest::covariances_assumed, for a pipeline that uses covariances
  /// (Pipeline::uses_covariances); then the verdict's reason ends with "; covariances assumed
  /// from the landmark spacing (...)" (after the left-out note, if any).
  bool covariances_assumed = false;

  /// One line: the preset, the termination, iterations, scores, time, the verdict.
  std::string BriefReport() const;
  /// Every stage's report, one per line: stages, changed settings, scales, the initialiser's
  /// report, the hypotheses' scores, the refinement, the diagnostics at the estimate, the
  /// covariances, the verdict.
  std::string FullReport() const;
  /// True when the estimate is finite and the last refinement ended with a step that determined
  /// it (not without pairs, not degenerate). Says nothing of trust: see verdict.
  bool IsSolutionUsable() const;
  /// The estimate as a similarity: scale.scale with registration.T_target_source.
  Similarity3 similarity() const { return {scale.scale, registration.T_target_source}; }
};

/// The one serialisation of a result, as JSON text (`indent` < 0: one line): the preset, its
/// stages and every setting, T_target_source (4x4, row-major rows), termination, iterations,
/// scores, time, usable, the verdict (trustworthy, trust_reason, source_landmarks_left_out and
/// target_landmarks_left_out, covariances_assumed, and its evidence: inlier and
/// overlap fractions, or the gated inliers, NIS and ambiguity), the initialiser's report, the
/// refined hypotheses, the diagnostics at the estimate, covariance_6x6 (the reported one;
/// row-major, xi = (rho [m], phi [rad]) on the left in the target frame; null when not
/// determined), the estimator's, and the history if recorded. Non-finite numbers are null. The
/// CLI's `align --json` results, Python's AlignmentResult.to_json(), the experiment and the
/// merge all write this.
std::string to_json(const Summary& summary, int indent = -1);

/// The registry of stages (stages/registry.cpp): one row per stage.
struct StageInfo {
  Seam seam;
  std::string name;
  std::string doc;
  std::vector<SettingRow> (*settings)();
  std::unique_ptr<Stage> (*make)(const Settings&);
};
const std::vector<StageInfo>& stage_registry();
/// Nullptr when no stage of that seam has that name.
const StageInfo* find_stage(Seam seam, const std::string& name);
/// The engine's own settings: the fitness score's range and the scale search's (scale.*).
std::vector<SettingRow> engine_settings();

class Pipeline {
 public:
  /// Builds the stages. Throws InvalidArgument for an unknown stage (naming the seam, the stage
  /// and the known ones), stages that do not fit together (an estimator that needs the pairs'
  /// covariances after a point matcher), an unknown setting (naming the nearest known key) or a
  /// value outside its bound (naming key, value and bound).
  explicit Pipeline(const PipelineSpec& spec);
  ~Pipeline();
  Pipeline(Pipeline&&) noexcept;
  Pipeline& operator=(Pipeline&&) noexcept;

  /// Aligns the source onto the target. Throws InvalidArgument on an empty source or target, a
  /// landmark that is not finite or beyond the supported range (core/supported_range.hpp;
  /// align() of presets.hpp leaves those out first), covariance counts that do not match, a
  /// non-rigid initial guess or one whose translation is beyond the range, an invalid prior or one
  /// for an initialiser that does not use it, or what a stage needs and does not get (weights,
  /// covariances).
  Summary run(const SourceView& source, const PreparedTarget& target,
              const PipelineRequest& request = {}) const;

  const PipelineSpec& spec() const { return spec_; }
  const Settings& settings() const { return settings_; }
  const Initialiser& initialiser() const { return *initialiser_; }
  const Matcher& matcher() const { return *matcher_; }
  const std::vector<std::unique_ptr<Rejector>>& rejectors() const { return rejectors_; }
  const Kernel& kernel() const { return *kernel_; }
  const Estimator& estimator() const { return *estimator_; }
  const Schedule& schedule() const { return *schedule_; }
  const Scorer* scorer() const { return scorer_.get(); }
  const TrustJudge* trust() const { return trust_.get(); }
  bool needs_scales() const { return needs_scales_; }
  /// The target landmark confidences its stages read (kUniform omitted), in seam order.
  std::vector<WeightKind> confidences() const;
  /// True when the result depends on the landmark covariances: a matcher that pairs
  /// distributions (its gate and the point-to-distribution cost) or a covariance confidence
  /// (Eq. 1).
  bool uses_covariances() const;

  /// One refinement from `start` in `phase` on the landmarks of `context`. `keep_pairs`: keep
  /// the last iteration's pairs in the result. `history`: 0 none, 1 pairs, 2 pairs and scores.
  /// `matcher_state`: the matcher's state to match with (from matcher().begin(); its caches,
  /// warm from a fitness score at the start, then serve the score at the estimate), or null
  /// for a state of the refinement's own. A free-scale refinement ignores it: it matches a
  /// rescaled copy of its source, with a state of its own begun again whenever the scale
  /// changes (the caches hold positions of the source at the old scale).
  Refinement refine(const RefineContext& context, const Hypothesis& start, Phase phase,
                    bool keep_pairs = false, int history = 0,
                    StageState* matcher_state = nullptr) const;
  /// refine() on the source landmarks `indices` (increasing) of `context`, copied out.
  /// `whole_matcher_state` (optional): a matcher state of the whole source (its caches warm, e.g.
  /// from a match at `start`); the part's state is made from it (Matcher::part_state), and the
  /// result is the same as without it.
  Refinement refine_part(const RefineContext& context, const std::vector<std::uint32_t>& indices,
                         const Hypothesis& start, Phase phase,
                         const StageState* whole_matcher_state = nullptr) const;

 private:
  PipelineSpec spec_;
  Settings settings_;
  std::unique_ptr<Initialiser> initialiser_;
  std::unique_ptr<Matcher> matcher_;
  std::vector<std::unique_ptr<Rejector>> rejectors_;
  std::unique_ptr<Kernel> kernel_;
  std::unique_ptr<Estimator> estimator_;
  std::unique_ptr<Schedule> schedule_;
  std::unique_ptr<Scorer> scorer_;
  std::unique_ptr<TrustJudge> trust_;
  bool needs_scales_ = false;
};

}  // namespace lmalign
