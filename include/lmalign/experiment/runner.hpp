// Running the cases of an experiment config (docs/experiments.md, "Running").
//
// Every (case, strategy) pair is one run: the source displaced by the case's D, aligned from the
// identity onto one shared PreparedTarget by align(preset, ...) (registration/presets.hpp), with
// the config's k, limits and settings, as `lmalign align` would. Runs execute in parallel (OpenMP,
// dynamic schedule); the ICP's own parallel loops then run single-threaded inside each worker.
// Results are stored by run index, so the outcome is identical for any thread count and schedule.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/geometry.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/registration.hpp"

namespace lmalign {

/// Which rule decided a run's success.
enum class SuccessCriterion {
  kGroundTruth,  ///< rotation and translation errors against the known true transform
  kScore,        ///< final score below the threshold (no ground truth, as the paper)
};
std::string to_string(SuccessCriterion c);  ///< "ground_truth", "score"

struct SuccessDecision {
  bool success = false;
  SuccessCriterion decided_by = SuccessCriterion::kScore;
};

/// With an error (ground truth known): success = rotation_deg < criteria.rotation_deg and
/// translation_m < criteria.translation_m. Without: final_score_m2 < criteria.score_m2.
/// Non-finite values never succeed.
SuccessDecision decide_success(const SuccessCriteria& criteria,
                               const std::optional<TransformError>& error, double final_score_m2);

/// The outcome of one run.
struct RunRecord {
  std::size_t case_index = 0;
  std::string strategy;  ///< the preset's name
  int k = 5;
  double initial_score_m2 = 0.0;
  double final_score_m2 = 0.0;
  int iterations = 0;
  TerminationReason termination = TerminationReason::kNotTerminated;
  /// Wall time of the alignment, seconds (the only value that differs between identical runs).
  double time_s = 0.0;
  /// The estimate for the displaced source (p_target = T * D * p_source).
  Isometry3 T_target_source = Isometry3::Identity();
  /// Error of the recovered map-to-map transform T * D against the ground truth, if known.
  std::optional<TransformError> error;
  SuccessDecision decision;
  /// The trust verdict of the preset's trust judge on the estimate (false for a non-finite one).
  bool trustworthy = false;
  /// The estimate's 6x6 covariance as the preset reports it (Summary::covariance;
  /// registration/uncertainty.hpp's convention: left perturbation, target frame). Its worst-axis
  /// standard deviations (metres, degrees), and the
  /// NEES of the recovered map-to-map transform T * D against the ground truth (6 dof: mean 6
  /// when the covariance is calibrated). Empty without a valid covariance (the NEES also without
  /// ground truth).
  std::optional<double> covariance_translation_sd_m;
  std::optional<double> covariance_rotation_sd_deg;
  std::optional<double> nees;
  /// Per-iteration record, for the history case only (with scores).
  std::vector<IterationRecord> history;
};

/// The maps and truth an experiment runs on, loaded per the config.
struct ExperimentInputs {
  Map source;
  Map target;
  /// True T_target_source of the undisplaced source, if the config gives one.
  std::optional<Isometry3> ground_truth;
  /// Landmarks left out on load for a coordinate beyond the supported range
  /// (core/supported_range.hpp), as align() of presets.hpp leaves them out of `lmalign align`.
  std::size_t source_left_out = 0;
  std::size_t target_left_out = 0;
};

/// Reads (and, for split specs, cuts) the source and target maps and the ground truth. Leaves out
/// the landmarks beyond the supported range, counted. Throws what read_map(), split_map() and
/// read_transform() throw, and InvalidArgument if a map has no landmarks (left).
ExperimentInputs load_experiment_inputs(const ExperimentConfig& config);

struct RunnerProgress {
  std::size_t runs_done = 0;
  /// Runs planned; shrinks when an escalation stops a quadrant early.
  std::size_t runs_total = 0;
  std::size_t cases_done = 0;
  std::size_t cases_total = 0;
};

struct RunnerOptions {
  /// Worker threads; 0 = every core.
  int threads = 0;
  /// Record per-iteration history with scores for the runs of this case.
  std::optional<std::size_t> history_case;
  /// Checked before each run starts; once set, no new run starts and run_cases() returns.
  const std::atomic<bool>* cancel = nullptr;
  /// Called after every finished run, and
  std::function<void(const RunnerProgress&)> on_progress;
  /// called when every run of a case has finished, with its records in strategy order. Both are
  /// called under one mutex (never concurrently), from whichever worker finished; they may throw,
  /// which stops the run and propagates from run_cases().
  std::function<void(const Case&, const std::vector<RunRecord>&)> on_case_finished;
  /// Records of cases finished by an earlier, interrupted run (read_results_csv(), for
  /// `lmalign experiment --resume`): these cases are not run again; their records go into the
  /// outcome as they are and count for the escalations. Each case present must have all its
  /// strategies, in order. on_case_finished is not called for them.
  std::vector<RunRecord> already_finished;
  /// The undisplaced source landmarks' position covariances (m^2, one per source point, source
  /// frame), for the presets whose stages read them (the adaptive default's gate); each run
  /// rotates them by its displacement D (R_D C R_D^T) as it moves the points. Not owned; null =
  /// none.
  const std::vector<Mat3>* source_covariances_m2 = nullptr;
  /// The undisplaced source map's up axis (source frame; estimate_up_axis()), for the adaptive
  /// strategy's yaw search; each run rotates it by its displacement. None: the pipeline's default.
  std::optional<Vec3> source_up;
  /// The undisplaced source landmarks' unit mean viewing directions (source frame;
  /// Map::view_directions()), for the gate's viewing-direction test; each run rotates them by
  /// its displacement. Not owned; null = none.
  const std::vector<Vec3>* source_view_directions = nullptr;
  /// What the two maps' headers say (scale, assumed covariances), passed to every run with
  /// AlignRequest::describe_maps, so a config's `scale: auto` means what `lmalign align --scale
  /// auto` means. Default: metric, measured covariances.
  MapHeader source_header;
  MapHeader target_header;
  /// Runs whose results are provably those of another run of the same wave are not executed but
  /// take a copy of its record, time_s included (docs/experiments.md, "Running"): the same
  /// displacement D (bit for bit) and the same correspondence rule. Base ignores k, and the
  /// weighted kNN with k = 1 picks the nearest neighbour when every target weight of its kind is
  /// positive, so runs whose pipelines then agree stage for stage and setting for setting share.
  /// The history case always runs. false: run everything.
  bool share_identical_runs = true;
};

struct RunnerOutcome {
  /// Records of the finished cases, by case index then in the case's strategy order.
  std::vector<RunRecord> records;
  std::size_t cases_finished = 0;
  /// Cases that were to run (all cases minus those an escalation skipped).
  std::size_t cases_planned = 0;
  /// Escalation levels not run because their quadrant stopped.
  std::size_t cases_skipped = 0;
  /// Records copied from an identical run instead of being run (share_identical_runs).
  std::size_t runs_shared = 0;
  bool cancelled = false;
};

/// Runs `cases` (from expand_cases(config, ...)). `source_points` are the undisplaced source
/// landmarks; `target` is shared by all runs; `ground_truth` is the true T_target_source of the
/// undisplaced source, or nullopt. Escalations run level by level: a quadrant's next offset runs
/// only if every strategy succeeded at the previous one (with stop: all, if any did).
/// Throws InvalidArgument on invalid settings (before any run) and whatever a callback throws.
RunnerOutcome run_cases(const ExperimentConfig& config, const std::vector<Case>& cases,
                        const Points3& source_points, const PreparedTarget& target,
                        const std::optional<Isometry3>& ground_truth,
                        const RunnerOptions& options = {});

/// What RunnerOptions points at for an experiment's source map: its landmarks' covariances
/// (m^2, source frame) and unit mean viewing directions (source frame), owned by the caller and
/// alive while run_cases() runs.
struct SourceDescription {
  std::vector<Mat3> covariances_m2;
  std::vector<Vec3> view_directions;
};

/// Sets the options' source_covariances_m2 and source_view_directions (pointing into `kept`,
/// which this fills), source_up (estimate_up_axis() of the source) and both headers from the
/// loaded inputs: what `lmalign experiment` and the Python package's experiment pass.
void describe_inputs(const ExperimentInputs& in, SourceDescription& kept, RunnerOptions& options);

/// The request of one run of `strategy` at neighbourhood size k: the config's limits (when it
/// gives them), its settings and scale mode for that strategy, and what the maps' headers say
/// (options.source_header, target_header: AlignRequest::describe_maps), as `lmalign align`
/// passes its options.
AlignRequest run_request(const ExperimentConfig& config, const std::string& strategy, int k,
                         const RunnerOptions& options = {});

}  // namespace lmalign
