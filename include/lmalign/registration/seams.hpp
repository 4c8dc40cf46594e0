// The seams of the registration engine (pipeline.hpp): the interfaces its stages implement,
// and the plain data that passes between them.
//
//   Initialiser  the hypotheses to refine (poses, each with the pose uncertainty the gate starts
//                from) and a report the trust judge reads (what the search found and certified)
//   Matcher      which target landmark each source landmark is paired with, within the current
//                gate (a Euclidean distance, or the landmark covariances widened by the pose
//                uncertainty)
//   Rejector     pairs dropped after matching (mutual nearest neighbours, trimming)
//   Kernel       each pair's weight (robust kernel times landmark confidence)
//   Estimator    the new pose from the weighted pairs, and its covariance
//   Schedule     the gate's schedule (levels of distance, or of pose uncertainty) and when to stop
//   Scorer       a refined hypothesis' score, which picks the best one
//   TrustJudge   whether the result can be trusted, from every refined hypothesis, their scores
//                and the initialiser's report
//
// Each seam is called once per stage per iteration, never per landmark: what a stage does per
// landmark it does in its own loop, one slot per landmark, so that results do not depend on the
// thread count. Stages are immutable once built (a pipeline refines several hypotheses at once);
// what a stage keeps during one refinement lives in the StageState it returns from begin().
//
// Frames: T_target_source, p_target = T_target_source * p_source. Units in names.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

// The plain data the seams pass (pairs, gates, scales, covariances, settings values); the
// classes they only point to are declared below. The definitions: src/registration/seams.cpp.
#include "lmalign/core/types.hpp"
#include "lmalign/registration/convergence.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/registration/settings.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "lmalign/registration/uncertainty.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {

class Map;
class Pipeline;
class PreparedTarget;
struct FitnessScore;
struct RefineContext;

/// The source landmarks as the engine reads them (not owned): positions (metres, source frame),
/// optional covariances (one 3x3 per landmark, m^2, source frame; null or empty = none) and an
/// optional up axis (unit, source frame). The pointed-to vectors must outlive the alignment.
struct SourceView {
  const Points3* positions = nullptr;
  const std::vector<Mat3>* covariances_m2 = nullptr;
  std::optional<Vec3> up;
  /// Unit mean viewing directions (source frame; Map::view_directions()), zero where unknown;
  /// null or empty = none.
  const std::vector<Vec3>* view_directions = nullptr;

  std::size_t size() const { return positions != nullptr ? positions->size() : 0; }
  bool has_covariances() const { return covariances_m2 != nullptr && !covariances_m2->empty(); }
  bool has_view_directions() const {
    return view_directions != nullptr && !view_directions->empty();
  }
};

/// The source landmarks, owned: what front ends build from a map or from arrays.
struct SourceLandmarks {
  Points3 positions;
  std::vector<Mat3> covariances_m2;  ///< empty = none
  std::optional<Vec3> up;
  std::vector<Vec3> view_directions;  ///< unit, source frame, zero where unknown; empty = none
  /// From a map: positions, covariances, the up axis of its frames (estimate_up_axis()) and the
  /// landmarks' viewing directions (Map::view_directions()). Throws InvalidArgument if the map
  /// is invalid.
  static SourceLandmarks from_map(const Map& map);
  /// The same landmarks displaced by T (p' = T p, C' = R C R^T, the up axis and the viewing
  /// directions rotated by R): the paper's protocol moves the source so before aligning it.
  SourceLandmarks moved(const Isometry3& T) const;
  SourceView view() const { return {&positions, &covariances_m2, up, &view_directions}; }
};

/// The scales read off the data (stages/data_scales.hpp), for the stages that need them.
struct Scales {
  DataScales source;
  DataScales target;
  /// Covariance floor of the gate, metres: the larger of the two maps' (or a setting).
  double floor_m = 0.0;
  /// The maps' up axes (unit, each in its own frame): their frames', else the default.
  Vec3 up_source = Vec3::UnitZ();
  Vec3 up_target = Vec3::UnitZ();
  /// The gated score's evidence scale in landmark spacings (setting scales.evidence_spacings;
  /// 1, the default; 0: off): see evidence() and pair_evidence (stages/mahalanobis_gate.hpp).
  double evidence_spacings = 1.0;
  /// The evidence scale is at least this many standard deviations of a pair of two typical
  /// landmarks (setting scales.evidence_typical_sigmas, default 2): where every landmark is
  /// vaguer than the spacing (a dense desk map), vagueness is the map's norm and tells no pose
  /// from another; only the vague tail is weighed down.
  double evidence_typical_sigmas = 2.0;
  /// Each map's evidence scale, in its own units (EvidenceScales; off when evidence_spacings is
  /// 0): e = max(evidence_spacings x its landmark spacing, evidence_typical_sigmas x sqrt(2) x
  /// sqrt(sigma^2 + floor^2)), sigma its typical landmark standard deviation
  /// (DataScales::sigma_m) and floor its own (DataScales::floor_m): a pair of two typical
  /// landmarks of alike maps has sqrt(2) times one's standard deviation. Rescaling a map
  /// rescales its e with its covariances, so a pair's weight does not depend on the scale.
  EvidenceScales evidence() const {
    EvidenceScales e;
    if (!(evidence_spacings > 0.0)) return e;
    auto of = [&](const DataScales& d) {
      const double typical = std::sqrt(d.sigma_m * d.sigma_m + d.floor_m * d.floor_m);
      return std::max(evidence_spacings * d.spacing_m,
                      evidence_typical_sigmas * std::sqrt(2.0) * typical);
    };
    e.source_m = of(source);
    e.target_m = of(target);
    e.floor_source_m = source.floor_m;
    e.floor_target_m = target.floor_m;
    return e;
  }
};

/// A pose the estimator works on: the rigid transform of the source the refinement works on,
/// and, with a free scale (Sim(3)), the factor by which that source is to be rescaled for it:
/// p_target = T_target_source * (scale * p_source). A 7-DoF step returns scale != 1; the
/// refinement then rescales its source by it (positions times scale, covariances times
/// scale^2) and goes on from scale 1.
struct Pose {
  Isometry3 T_target_source = Isometry3::Identity();
  double scale = 1.0;
};

// ----------------------------------------------------------------------------- stages

enum class Seam {
  kInitialiser,
  kMatcher,
  kRejector,
  kKernel,
  kEstimator,
  kSchedule,
  kScorer,
  kTrustJudge,
};
/// "initialiser", "matcher", "rejectors", "kernel", "estimator", "schedule", "scorer", "trust"
/// (the keys of a preset file).
std::string to_string(Seam seam);

/// What a stage keeps during one refinement (a search cache, a convergence test's memory).
class StageState {
 public:
  virtual ~StageState() = default;
};

/// The base of every stage: its registry name and what it needs of the pipeline.
class Stage {
 public:
  virtual ~Stage() = default;
  /// The stage's registry name ("nearest", "mahalanobis_gate", ...).
  const std::string& name() const { return name_; }
  void set_name(std::string name) { name_ = std::move(name); }
  /// True when the stage reads Scales (the engine measures them only then).
  virtual bool needs_scales() const { return false; }
  /// Whether the stage works on the pairs a matcher of this kind makes (point pairs, or pairs
  /// with their covariances); kPoints or kDistributions. The pipeline refuses stages that do not.
  virtual bool accepts(int pair_kind) const {
    (void)pair_kind;
    return true;
  }
  /// The target landmark confidence (weights.hpp: Eqs. 1-4) the stage reads, if any: a weighted
  /// kNN matcher's choice among the k nearest, a kernel's factor. kUniform reads none.
  virtual WeightKind confidence() const { return WeightKind::kUniform; }

 private:
  std::string name_;
};

// ----------------------------------------------------------------------------- initialiser

/// One hypothesis to refine.
struct Hypothesis {
  Isometry3 T_target_source = Isometry3::Identity();
  /// The pose uncertainty the gate starts from (translation about `pivot` below, metres;
  /// rotation, radians): how far the search's resolution or the prior leaves the pose.
  double start_sigma_m = 0.0;
  double start_sigma_rad = 0.0;
  /// The search's own score of the hypothesis (votes, a bound); 0 for the guess.
  double search_score = 0.0;
  /// Where it came from: "search", "guess", "prior", ...
  std::string origin;
  /// Caps on this refinement (0: the schedule's own): its iterations, and a schedule's
  /// iterations per level. A search that refines many candidates briefly sets them.
  int max_iterations = 0;
  int max_iterations_per_level = 0;
  /// With a free scale: the source's scale for this hypothesis relative to the run's current
  /// one (a rung of the scale axis, Pipeline::run); the pose moves the source rescaled by it.
  double scale_factor = 1.0;
  /// Refined and scored as a rival of the verdict, never the answer (a strict prior window's
  /// global check, init.prior_check = strict).
  bool rival_only = false;
};

/// What an initialiser tells the rest of the pipeline and the trust judge.
struct InitialiserReport {
  /// How the hypotheses were found: "global" (a search over every pose), "prior" (a search
  /// bounded by a prior), "given" (the initial guess alone), "global_vote" (the robust presets'
  /// global initialisation), "yaw_centroid".
  std::string initialisation = "given";
  /// The search's resolution: the largest translation (metres, at the source's typical distance
  /// from its centre) and rotation (radians) by which a hypothesis may miss the best pose of its
  /// cell. 0 when there was no search. Distinct poses, and the overlap, are measured in it.
  double resolution_m = 0.0;
  double resolution_rad = 0.0;
  /// Up-axis candidates the search used (empty when none).
  std::vector<Vec3> ups_source;
  std::vector<Vec3> ups_target;
  /// What the search certified, for the trust judge: the best search score, and the best score
  /// of a pose distinct from it (NaN when the search gives none). A complete search reports the
  /// bounds it proved here.
  double best_search_score = std::numeric_limits<double>::quiet_NaN();
  double second_search_score = std::numeric_limits<double>::quiet_NaN();
  /// With a prior: the global search ran too and its modes are among the hypotheses (issue 41);
  /// the verdict then checks that the answer lies in the prior's window.
  bool prior_checked = false;
  /// The hypotheses come from a cheaper pass than the initialiser's last, and a deeper search is
  /// available: Pipeline::run runs it (InitialiserContext::pass + 1) when this pass's answer is
  /// not trusted (deeper_if_untrusted) or is trusted but prior_unconfirmed, and reports that
  /// answer instead.
  bool deeper_pass = false;
  /// With a prior and deeper_pass: none of the first pass's poses lies inside the prior's
  /// window, so the hypotheses inside it are the prior's own search's, and the first pass's
  /// modes are their only rivals. A trusted answer then still needs the deeper pass's rivals;
  /// an answer outside the window that every other test trusts (Verdict::
  /// trusted_but_for_prior_window) stands: the maps prefer it, and no deeper pass can make the
  /// result trusted.
  bool prior_unconfirmed = false;
  /// With deeper_pass: the deeper pass also runs when this pass's answer is not trusted. False
  /// (the maps' first pass under a prior with init.prior_complete_search = "check"): the
  /// complete search runs only to check a trusted answer that prior_unconfirmed leaves without
  /// the maps' own rivals.
  bool deeper_if_untrusted = true;
  /// With deeper_if_untrusted: an untrusted answer goes deeper only when the maps support it at
  /// all (not Verdict::no_evidence). Set by a prior's own search under init.
  /// prior_complete_search = "check": fewer than trust.min_inliers landmarks agree anywhere in
  /// the prior's window, and a deeper pass's answer could be trusted only inside that window
  /// (a fleet's candidate pairs that do not overlap then cost the prior's search alone).
  bool deeper_needs_evidence = false;
  /// Non-empty: the initialiser proposes nothing, and this says why (the complete search's
  /// search.complete_search = check when the first pass finds no pose). The result is then not
  /// trusted, with this reason, its pose the initial guess (Pipeline::run).
  std::string declined;
  /// Other numbers worth a line in the report (name, value).
  std::vector<std::pair<std::string, double>> notes;
};

/// What an initialiser may read.
struct InitialiserContext {
  SourceView source;
  const PreparedTarget* target = nullptr;
  const Scales* scales = nullptr;  ///< null unless a stage needs them
  /// The initial guess (T_target_source) and its prior (standard deviations of the rotation,
  /// degrees, and of the translation, metres, about the target origin), if given.
  std::optional<Isometry3> initial_guess;
  std::optional<std::pair<double, double>> prior_sigma_deg_m;
  /// The pipeline and every source landmark: an initialiser may refine its candidates with
  /// the pipeline's own refinement (Pipeline::refine_part, Phase::kHypothesis).
  const Pipeline* pipeline = nullptr;
  const RefineContext* refine_context = nullptr;
  /// 0: the initialiser may propose from a first, cheapest pass (and say so in
  /// InitialiserReport::deeper_pass); each later pass, 1, 2, ..., runs after the previous pass's
  /// answer did not settle the alignment (Pipeline::run), until a pass reports no deeper one.
  int pass = 0;
  /// True when this pass checks the previous pass's trusted answer for its rivals (Pipeline::run:
  /// its verdict needs every rival), an answer the maps' own poses found (not a prior's
  /// unconfirmed window, InitialiserReport::prior_unconfirmed) and trusted without a prior's
  /// waiver of the alias test (Verdict::alias_waived_by_prior): the answer is among the
  /// hypotheses, and the pass need only find its rivals.
  bool checking = false;
  /// True when the scale is free (a similarity): a check then uses the complete search, whatever
  /// search.check says (docs/scale.md, "Measured": on a real KITTI pair moved by similarities a
  /// second correspondence search saw a wrong answer's rival at 54%, the complete search at 85%).
  bool free_scale = false;
  /// Free scale: the poses the scale's measurement found at the measured scale
  /// (ScaleMeasurement::poses: T_target_source of context.source, which is then at that
  /// scale); a first pass may take them instead of searching again. Empty otherwise.
  std::vector<Isometry3> measured_poses;
};

/// What Initialiser::measure_scale found: the factor (target units per source unit, relative
/// to the context's source) and the poses its evidence gives at that factor (T_target_source
/// of the source multiplied by it), best first; whether that evidence is decisive; and the
/// evidence itself, each consistent clique's scale factor and matches.
struct ScaleMeasurement {
  double factor = 1.0;
  std::vector<Isometry3> poses;  ///< empty when not decisive
  /// At least `margin` times the matches of the largest clique at a scale more than a ratio
  /// away: the factor replaces the searches again. Otherwise the cliques only order them
  /// (ScaleSearch::set_evidence).
  bool decisive = true;
  /// (factor, matches) of every clique found, in the search's order.
  std::vector<std::pair<double, std::size_t>> cliques;
};

class Initialiser : public Stage {
 public:
  /// The hypotheses (at least one) and the report. Deterministic.
  virtual std::vector<Hypothesis> propose(const InitialiserContext& context,
                                          InitialiserReport* report) const = 0;
  /// True when the initialiser searches on its own and ignores an initial guess it is not given.
  virtual bool uses_prior() const { return false; }
  /// Free scale (registration/scale_search.hpp): the factor by which the source's lengths
  /// should be multiplied to match the target's, as the maps' own correspondences measure it
  /// (target units per source unit, relative to context.source; tried at ratio^k, |k| <=
  /// steps). Empty when this initialiser measures nothing (the default) or found no clique;
  /// `decisive` false when its evidence is fewer than `margin` times the evidence for a scale
  /// more than a ratio away (then only its cliques count). Deterministic.
  virtual std::optional<ScaleMeasurement> measure_scale(const InitialiserContext& /*context*/,
                                                        int /*steps*/, double /*ratio*/,
                                                        double /*margin*/) const {
    return std::nullopt;
  }
};

// ----------------------------------------------------------------------------- the loop

/// Which refinement the loop runs.
enum class Phase {
  kHypothesis,  ///< a hypothesis on the samples, from its start uncertainty
  kFinal,       ///< the best hypothesis on every landmark
  kResample,    ///< a part of the landmarks from the estimate (half-sample covariance)
};

/// What the schedule keeps and every stage of the loop may read.
struct LoopState {
  Phase phase = Phase::kFinal;
  int iterations = 0;        ///< steps taken in this refinement
  int level_iterations = 0;  ///< since the schedule last changed its level
  /// The refinement's cap on a schedule's iterations per level (0: none; Hypothesis).
  int max_iterations_per_level = 0;
  std::size_t level = 0;  ///< the schedule's level
  /// The Euclidean gate of point matchers at this level, metres (+inf = none).
  double max_distance_m = std::numeric_limits<double>::infinity();
  /// The pose uncertainty that widens the gate of distribution matchers; its pivot is the
  /// source centre's image at the current estimate.
  PoseSigma sigma;
  /// The trimming rejector's last ratio (1 without trimming).
  double overlap_ratio = 1.0;
  /// Diagnostics at the estimate after the last step: rejectors reuse their last ratio.
  bool final_pass = false;
  /// The estimator's cost this iteration uses the pair covariances (kernels then may measure
  /// residuals in their metric).
  bool distribution_step = false;
  /// The scale is estimated too (Sim(3)): an estimator that estimates_scale() solves 7 DoF.
  bool free_scale = false;
  /// The pairs score a pose (the scorer, the trust judge) instead of feeding a step. The gate's
  /// viewing-direction test (match.max_view_angle_deg) applies only then: inside the loop, a
  /// pair at the test's boundary flips in and out from one step to the next (full weight, unlike
  /// the chi-square boundary where the kernel's weight is small) and the refinement never
  /// settles (measured on a real desk window: a 2-cycle of 843/844 pairs to the iteration limit).
  bool scoring = false;
  static LoopState for_scoring() {
    LoopState s;
    s.scoring = true;
    return s;
  }
};

/// The pairs of one iteration. Point matchers fill `moved` and `points`; distribution matchers
/// fill `gated`. `weights`, set by the kernel, has one weight per pair (empty: all 1).
struct Pairs {
  enum class Kind { kPoints, kDistributions };
  Kind kind = Kind::kPoints;
  Points3 moved;                 ///< T * p for every source landmark of the refinement
  Correspondences points;        ///< in increasing source index
  std::vector<GatedPair> gated;  ///< in increasing source index
  std::vector<double> weights;
  /// Distribution matchers: the gate on d^2 (dimensionless).
  double chi2_threshold = 0.0;
  std::size_t size() const { return kind == Kind::kPoints ? points.size() : gated.size(); }
};

/// What every stage of one refinement reads: the landmarks of the refinement (all, or a part
/// copied out), the target, the scales (or null), the initialiser's report.
struct RefineContext {
  SourceView source;
  const PreparedTarget* target = nullptr;
  const Scales* scales = nullptr;
  const InitialiserReport* init = nullptr;
  /// The run estimates the scale (PipelineRequest::free_scale): final and resampled refinements
  /// then solve 7 DoF with an estimator that can, rescaling a copy of their source as it goes.
  bool free_scale = false;
};

class Matcher : public Stage {
 public:
  /// What kind of pairs it makes.
  virtual Pairs::Kind kind() const = 0;
  virtual std::unique_ptr<StageState> begin(const RefineContext& context) const = 0;
  /// Replaces *pairs with the pairs at T within the state's gate. Parallel inside, one slot per
  /// landmark; the pairs in increasing source index.
  virtual void match(const RefineContext& context, StageState* state, const Isometry3& T,
                     const LoopState& loop, Pairs* pairs) const = 0;
  /// A state for the part of the source made of the landmarks `indices` (increasing; the part's
  /// landmark j is the whole's indices[j]), carrying what `whole` holds of them: refine_part()
  /// then matches as with a fresh state, faster. Null (the default): a fresh state.
  virtual std::unique_ptr<StageState> part_state(const StageState& whole,
                                                 const std::vector<std::uint32_t>& indices) const {
    (void)whole;
    (void)indices;
    return nullptr;
  }
  /// True when a state stays exact after the source's landmarks move in place (a free scale
  /// rescales them at every step): its caches check each seed against where the landmark now is
  /// (the Mahalanobis gate's GateNeighbourCache), so a free-scale refinement keeps its state and
  /// may start from a whole's. False (the default): it begins a new state after each rescale.
  virtual bool state_follows_the_source() const { return false; }
  /// PCL's fitness score at T (score.hpp), served from the state's caches where it can be.
  virtual FitnessScore fitness(const RefineContext& context, StageState* state, const Isometry3& T,
                               double max_range_m) const;
};

class Rejector : public Stage {
 public:
  /// Drops pairs (keeping the order); may record what it did in *loop (the trim ratio).
  virtual void reject(const RefineContext& context, LoopState* loop, Pairs* pairs) const = 0;
};

class Kernel : public Stage {
 public:
  /// Re-weightings per iteration on fixed pairs (iteratively re-weighted least squares), >= 1.
  virtual int reweightings() const { return 1; }
  /// Writes one weight per pair into *weights (or clears it: all 1), for the estimate
  /// increment * T (the pairs were made at T).
  virtual void weigh(const RefineContext& context, const LoopState& loop, const Pairs& pairs,
                     const Isometry3& T, const Isometry3& increment,
                     std::vector<double>* weights) const = 0;
};

/// One solved step.
struct Step {
  /// False: the normal equations were singular or the step not finite (the loop then stops with
  /// kDegenerate, keeping the estimate).
  bool ok = true;
  Pose estimate;                                ///< the new estimate
  Isometry3 increment = Isometry3::Identity();  ///< the step as a left increment
  /// The step's own parameters about `pivot_m` (rho [m], phi [rad], sigma = log scale [1]; sigma
  /// 0 unless the scale is free) when the estimator has them.
  bool has_xi = false;
  Vec7 xi = Vec7::Zero();
  Vec3 pivot_m = Vec3::Zero();
  /// A minimiser among many (rank-deficient cross-covariance, singular point-to-distribution).
  bool degenerate = false;
  /// The normal equations the step solved, about pivot_m (for the covariance): sum w J^T W J in
  /// the step's unknowns (the scale's row and column zero when it is fixed), and the weighted
  /// chi-square before the step.
  Mat7 hessian = Mat7::Zero();
  int dof = 6;
  double chi2 = 0.0;
};

class Estimator : public Stage {
 public:
  /// Pairs it needs at least (fewer: the loop stops with kNoCorrespondences).
  virtual std::size_t min_pairs() const { return 1; }
  virtual Pairs::Kind needs() const = 0;
  /// 6, or 4 for x, y, z and yaw (without the scale).
  virtual int degrees_of_freedom() const { return 6; }
  /// True when it also solves the scale (7 DoF) in a loop whose free_scale is set.
  virtual bool estimates_scale() const { return false; }
  /// True when this iteration's cost uses the pair covariances.
  virtual bool distribution_step(const LoopState&) const { return false; }
  /// The step from `pairs` (weighted) at `current`; `increment` is the re-weighting's estimate
  /// so far (identity at the first), from which a Gauss-Newton solver may start.
  virtual Step solve(const RefineContext& context, const LoopState& loop, const Pairs& pairs,
                     const Pose& current, const Isometry3& increment) const = 0;
  /// The 6x6 covariance of the estimate (uncertainty.hpp's convention; with loop.free_scale also
  /// the 7x7 with the scale, PoseCovariance::covariance_7x7), from `pairs` (weighted):
  /// the pairs at the estimate, or those the last step was solved on (then `last_step` is that
  /// step). Cheap: no refinement is run.
  virtual PoseCovariance covariance(const RefineContext& context, const Pipeline& pipeline,
                                    const LoopState& loop, const Pairs& pairs, const Pose& estimate,
                                    const Step* last_step) const = 0;
  /// `estimator_covariance` (covariance()'s at `estimate`) raised where re-running the pipeline's
  /// refinement on parts of the landmarks (a resampling: half samples) says the estimate is less
  /// certain; the parts used counted in *num_resamples (may be null). `context.free_scale` as
  /// for covariance(). Costly (several refinements of the overlap): the pipeline asks for it
  /// only where it matters, for a trusted answer and for a verdict that weighs the standard
  /// deviations (JudgeContext::resampled_covariance). Default: `estimator_covariance` itself.
  virtual PoseCovariance resampled_covariance(const RefineContext& context,
                                              const Pipeline& pipeline, const Pose& estimate,
                                              const PoseCovariance& estimator_covariance,
                                              std::size_t* num_resamples) const {
    (void)context;
    (void)pipeline;
    (void)estimate;
    (void)num_resamples;
    return estimator_covariance;
  }
};

class Schedule : public Stage {
 public:
  /// Where the estimator's covariance and the diagnostics come from once the loop stops.
  enum class EndPass {
    kNone,        ///< nothing (the paper's ICP)
    kLastStep,    ///< the last step's normal equations and pairs
    kAtEstimate,  ///< the last level's pairs re-made at the estimate (and the diagnostics)
  };
  virtual EndPass end_pass() const { return EndPass::kNone; }
  /// Starts a refinement: sets the gate of *loop (level 0, its distance or pose uncertainty).
  virtual std::unique_ptr<StageState> begin(const RefineContext& context, const Hypothesis& start,
                                            LoopState* loop) const = 0;
  /// Pairs needed to go on.
  virtual std::size_t min_pairs() const { return 1; }
  /// True when after_step() ends a free-scale refinement only once its scale has settled by the
  /// schedule's own measure (sigma_anneal: a scale step that moves a landmark at the source's
  /// radius less than the settle threshold). False (the default): the pipeline also goes on
  /// while a step changes the scale by more than `scale.settle` (relative).
  virtual bool settles_scale() const { return false; }
  /// Checked before each iteration: false stops with kMaxIterations.
  virtual bool may_iterate(const LoopState&) const { return true; }
  /// After a step (loop->iterations counts it): kNotTerminated to go on, else why it stops. May
  /// change the level (and the gate) in *loop.
  virtual TerminationReason after_step(const RefineContext& context, StageState* state,
                                       const Step& step, const Pairs& pairs,
                                       LoopState* loop) const = 0;
  /// The settings that apply a user's limits to this schedule (`lmalign align --max-iterations /
  /// --max-distance`): an iteration budget, and a cap on the correspondence distance where the
  /// schedule has one (none: nothing to cap). `current` is the pipeline's table. Throws
  /// InvalidArgument for a budget < 1 or a distance that is not > 0.
  virtual std::vector<std::pair<std::string, SettingValue>> limits(
      const Settings& current, std::optional<int> max_iterations,
      std::optional<double> max_distance_m) const = 0;
  /// The reason reported once stopped (`last_degenerate`: the last step was a minimiser among
  /// many).
  virtual TerminationReason finish(TerminationReason reason, bool last_degenerate) const {
    (void)last_degenerate;
    return reason;
  }
};

// ----------------------------------------------------------------------------- the result

/// One refinement, as the engine ran it.
struct Refinement {
  /// The estimate: p_target = T * (scale * p_source) for the refinement's source (scale = 1
  /// unless the refinement estimated it).
  Isometry3 T = Isometry3::Identity();
  double scale = 1.0;
  TerminationReason termination = TerminationReason::kNotTerminated;
  int iterations = 0;
  std::size_t num_pairs = 0;  ///< pairs of the last iteration
  LoopState loop;             ///< the loop's state at the end
  Step last_step;             ///< the last solved step (ok = false if none)
  bool has_step = false;
  Pairs last_pairs;  ///< the pairs the last step was solved on (final phase)
  std::vector<IterationRecord> history;
};

/// A refined hypothesis.
struct RefinedHypothesis {
  Hypothesis start;
  Isometry3 T_refined = Isometry3::Identity();
  /// The scorer's, on its scoring samples (Scorer::scoring_samples: every landmark for the
  /// gated scorer by default); the best hypothesis' becomes the answer's own when that is higher.
  double score = 0.0;
  int iterations = 0;
  TerminationReason termination = TerminationReason::kNotTerminated;
  /// The refinement from the start's own gate (start_sigma_*) scored below the start, and this
  /// is the refinement from the start with a sharp gate instead (zero pose uncertainty), which
  /// scored higher (PipelineRun::score_hypotheses): the guess always (it is never traded for a
  /// pose the score rates lower), a search's hypothesis when its start scores at least
  /// Scorer::sharp_restart_share of the best refined hypothesis.
  bool sharp_restart = false;
  /// A contender (Scorer::contenders; not in a first pass): refined again from its refined pose
  /// with a sharp gate on Scorer::contender_samples landmarks, and that refinement scored higher.
  bool refined_again = false;
};

class Scorer : public Stage {
 public:
  /// The source landmarks (indices, increasing) on which hypotheses are refined.
  virtual std::vector<std::uint32_t> samples(std::size_t num_landmarks) const = 0;
  /// The source landmarks (indices, increasing) on which a refined hypothesis is scored: the
  /// score that ranks the hypotheses and that the trust judge's rival test compares. By default
  /// the refinement's own samples.
  virtual std::vector<std::uint32_t> scoring_samples(std::size_t num_landmarks) const {
    return samples(num_landmarks);
  }
  /// The score of T on the context's landmarks (larger is better).
  virtual double score(const RefineContext& context, const Pipeline& pipeline,
                       const Isometry3& T) const = 0;
  /// A search's hypothesis whose refinement scores below its own start on the samples, and
  /// whose start scores at least this share of the best refined hypothesis on the scoring
  /// samples, is refined again from its start with a sharp gate (zero pose uncertainty), and the
  /// better of the two is kept (PipelineRun::score_hypotheses; docs/accuracy.md, "A hypothesis
  /// that loses to its start"). 0: never. Dimensionless, in [0, 1].
  virtual double sharp_restart_share() const { return 0.0; }
  /// In every search but a first pass that a deeper one may follow (InitialiserReport::
  /// deeper_pass: so in the complete search, a check of a trusted answer, a prior's search), the
  /// contenders: at most this many of the best refined hypotheses, each scoring at least
  /// contender_share() of the best, are refined again from their refined poses with a sharp
  /// gate on contender_samples() landmarks, and each keeps the better of its two poses
  /// (PipelineRun::score_hypotheses; docs/accuracy.md, "Contenders refined again"). A pose
  /// refined on a sample can stop short where the sample holds too few of the overlap's
  /// landmarks. 0: never.
  virtual std::size_t contenders() const { return 0; }
  /// See contenders(). Dimensionless, in [0, 1].
  virtual double contender_share() const { return 1.0; }
  /// The source landmarks (indices, increasing) on which the contenders are refined again.
  virtual std::vector<std::uint32_t> contender_samples(std::size_t num_landmarks) const {
    return scoring_samples(num_landmarks);
  }
};

/// The trust verdict and what it was decided on.
struct Verdict {
  bool trustworthy = false;
  std::string reason;  ///< "ok", or why not
  /// Point presets (judge "inliers"): source landmarks within the inlier distance, and within the
  /// overlap distance, of all (NaN otherwise).
  double inlier_fraction = std::numeric_limits<double>::quiet_NaN();
  double overlap_fraction = std::numeric_limits<double>::quiet_NaN();
  /// Every judge: the inliers at the estimate, and the inliers over the landmarks in the overlap.
  std::size_t num_inliers = 0;
  double inlier_ratio = 0.0;
  /// Covariance-gated evidence (judge "gated"; 0 otherwise): the inliers' score sum
  /// (1 - d^2 / chi2), their mean Mahalanobis d^2 (NIS) and its expectation, the landmarks near
  /// a target landmark (the gate widened by the search's resolution), and the best distinct
  /// hypothesis' score over the best's.
  double score = 0.0;
  double mean_nis = 0.0;
  double expected_nis = 0.0;
  std::size_t num_overlap = 0;
  double ambiguity = 0.0;
  /// The covariance scale k^2 (dimensionless): the factor by which the landmark covariances
  /// must be scaled for the inliers' median Mahalanobis d^2 to be that of a chi-square with 3
  /// dof truncated at the gate (1 when the covariances hold; judge "gated").
  double covariance_scale = 1.0;
  /// The best distinct rival of the estimate (judge "gated"; when ambiguity > 0): its pose, the
  /// distance between the two poses' images of the source centre (metres) and the rotation
  /// between them (degrees).
  std::optional<Isometry3> rival_T_target_source;
  double rival_distance_m = 0.0;
  double rival_angle_deg = 0.0;
  /// With a prior: the answer lies outside the prior's window (not trusted, the reason says
  /// where), and whether every other test of the judge trusted it.
  bool outside_prior_window = false;
  bool trusted_but_for_prior_window = false;
  /// The verdict needs every rival (judge "gated": the residuals exceed their covariances as
  /// repeated structure's aliases do, the mean NIS above trust.alias_nis_ratio of its
  /// expectation; or a rival already scores trust.alias_ambiguity of the answer): a trusted
  /// answer of an initialiser's first pass, whose few poses may miss them, is checked by its
  /// deeper pass (Pipeline::run).
  bool rivals_needed = false;
  /// With a prior (judge "gated"): the alias test would refuse the answer (a rival at
  /// trust.alias_ambiguity with residuals above their covariances), but the prior tells that
  /// rival apart (the answer inside its window, the rival outside): the answer is trusted on the
  /// prior's word, and a deeper pass that checks it searches completely (search.check).
  bool alias_waived_by_prior = false;
  /// Nothing in the maps supports the answer (judge "gated": no gated correspondence, or fewer
  /// gated inliers than trust.min_inliers): with InitialiserReport::deeper_needs_evidence, no
  /// deeper pass is tried.
  bool no_evidence = false;
  /// A covariance of the judge's own (judge "inliers": point-to-point on its inliers), reported
  /// instead of the estimator's.
  std::optional<PoseCovariance> covariance;
};

/// What the trust judge reads.
struct JudgeContext {
  RefineContext context;  ///< every source landmark
  const Pipeline* pipeline = nullptr;
  const Refinement* final = nullptr;
  const std::vector<RefinedHypothesis>* hypotheses = nullptr;  ///< by decreasing score
  const InitialiserReport* init = nullptr;
  const PoseCovariance* covariance = nullptr;  ///< the estimator's (Estimator::covariance)
  /// The estimator's covariance raised by its resampling (Estimator::resampled_covariance),
  /// computed on the first call (several refinements): a judge whose verdict weighs the
  /// standard deviations asks for it; validity is *covariance's. Null: *covariance is all there
  /// is.
  std::function<const PoseCovariance&()> resampled_covariance;
  /// The request's initial guess (T_target_source) and its prior (standard deviations of the
  /// rotation, degrees, and of the translation, metres, about the target origin), if given:
  /// InitialiserContext's.
  std::optional<Isometry3> initial_guess;
  std::optional<std::pair<double, double>> prior_sigma_deg_m;
};

class TrustJudge : public Stage {
 public:
  virtual Verdict judge(const JudgeContext& context) const = 0;
};

}  // namespace lmalign
