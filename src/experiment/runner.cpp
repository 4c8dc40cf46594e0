// Running the cases (docs/experiments.md, "Running"). One task per (case, strategy); OpenMP
// dynamic schedule over the tasks of a wave; results stored by task index. Escalations add one
// wave per level. Nothing here depends on the thread count or on timing except time_s.
#include "lmalign/experiment/runner.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <map>
#include <mutex>
#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

std::string to_string(SuccessCriterion c) {
  return c == SuccessCriterion::kGroundTruth ? "ground_truth" : "score";
}

SuccessDecision decide_success(const SuccessCriteria& criteria,
                               const std::optional<TransformError>& error, double final_score_m2) {
  SuccessDecision d;
  if (error) {
    d.decided_by = SuccessCriterion::kGroundTruth;
    d.success = std::isfinite(error->rotation_deg) && std::isfinite(error->translation_m) &&
                error->rotation_deg < criteria.rotation_deg &&
                error->translation_m < criteria.translation_m;
  } else {
    d.decided_by = SuccessCriterion::kScore;
    d.success = std::isfinite(final_score_m2) && final_score_m2 < criteria.score_m2;
  }
  return d;
}

namespace {

Map load_map(const MapSpec& spec, const std::string& role, std::size_t* left_out) {
  Map map;
  if (spec.split) {
    MapReadOptions ro;
    ro.min_observations = 0;  // count observations within the window, not in the whole map
    const Map full = read_any_map(spec.path, {ro});
    SplitOptions so;
    so.first_frame_id = spec.first_frame_id;
    so.last_frame_id = spec.last_frame_id;
    so.min_observations = std::max<std::size_t>(spec.min_observations, 1);
    so.retriangulate = spec.retriangulate;
    so.min_parallax_deg = spec.min_parallax_deg;
    map = split_map(full, so);
  } else {
    MapReadOptions ro;
    ro.min_observations = spec.min_observations;
    map = read_any_map(spec.path, {ro});
  }
  // The supported range (core/supported_range.hpp): landmarks beyond it are left out on load, for
  // the paper's strategies and lmalign's alike, and counted (ExperimentInputs).
  const std::size_t before = map.landmarks.size();
  map.landmarks.erase(
      std::remove_if(map.landmarks.begin(), map.landmarks.end(),
                     [](const Landmark& l) { return !within_supported_range(l.p_world); }),
      map.landmarks.end());
  if (left_out != nullptr) *left_out = before - map.landmarks.size();
  if (before > 0 && map.landmarks.empty()) {
    throw InvalidArgument(
        role + " map '" + spec.path + "': every landmark (" + std::to_string(before) +
        ") is beyond the supported range (|coordinate| <= " + message_number(kMaxCoordinateM) +
        " m)");
  }
  if (map.landmarks.empty()) {
    throw InvalidArgument(role + " map '" + spec.path + "' has no landmarks" +
                          (spec.split ? " in frames " + std::to_string(spec.first_frame_id) + "-" +
                                            std::to_string(spec.last_frame_id)
                                      : std::string()) +
                          " with at least " + std::to_string(spec.min_observations) +
                          " observations");
  }
  return map;
}

struct Task {
  std::size_t case_index;
  std::size_t slot;  // position of the strategy in the case
};

/// Sets OpenMP's max active levels to 1 for its lifetime: the ICP's parallel loops inside a
/// worker then run on that worker alone (no oversubscription).
class SingleLevelParallelism {
 public:
  SingleLevelParallelism() : saved_(omp_get_max_active_levels()) { omp_set_max_active_levels(1); }
  ~SingleLevelParallelism() { omp_set_max_active_levels(saved_); }
  SingleLevelParallelism(const SingleLevelParallelism&) = delete;
  SingleLevelParallelism& operator=(const SingleLevelParallelism&) = delete;

 private:
  int saved_;
};

}  // namespace

ExperimentInputs load_experiment_inputs(const ExperimentConfig& config) {
  ExperimentInputs in;
  in.source = load_map(config.source, "source", &in.source_left_out);
  in.target = load_map(config.target, "target", &in.target_left_out);
  switch (config.ground_truth.kind) {
    case GroundTruthSpec::Kind::kNone:
      break;
    case GroundTruthSpec::Kind::kIdentity:
      in.ground_truth = Isometry3::Identity();
      break;
    case GroundTruthSpec::Kind::kFile:
      in.ground_truth = read_transform(config.ground_truth.path);
      break;
  }
  return in;
}

AlignRequest run_request(const ExperimentConfig& config, const std::string& strategy, int k,
                         const RunnerOptions& options) {
  AlignRequest r;
  r.describe_maps(options.source_header, options.target_header);
  r.k = k;
  r.max_iterations = config.max_iterations;
  r.max_distance_m = config.max_distance_m;
  r.scale = config.scale_of(strategy);
  for (const auto& [name, values] : config.settings) {
    if (name == strategy) r.settings = values;
  }
  return r;
}

namespace {

// One run_cases() (runner.hpp), phase by phase: the checks, the records of an earlier run, waves
// of runs in parallel (runs with provably identical results shared), the escalation groups'
// next levels, the outcome.
class CaseRunner {
 public:
  CaseRunner(const ExperimentConfig& config, const std::vector<Case>& cases,
             const Points3& source_points, const PreparedTarget& target,
             const std::optional<Isometry3>& ground_truth, const RunnerOptions& options)
      : config_(config),
        cases_(cases),
        source_points_(source_points),
        target_(target),
        ground_truth_(ground_truth),
        options_(options) {}

  RunnerOutcome run() {
    validate();
    threads_ = options_.threads > 0 ? options_.threads : std::max(1, omp_get_num_procs());
    bookkeeping();
    preload();
    // The presets, read once (find_preset copies).
    for (const Case& c : cases_) {
      for (const std::string& s : c.strategies) {
        if (preset_of_.count(s) == 0) preset_of_.emplace(s, find_preset(s));
      }
    }
    // Wave 0: everything but escalation levels > 0 (and but the cases already finished).
    std::vector<Task> wave;
    for (const Case& c : cases_) {
      if (preloaded_[c.index]) continue;
      if (c.escalation_group < 0 || c.escalation_level == 0) add_case(&wave, c.index);
    }
    next_level_.assign(groups_.size(), 1);
    for (;;) {
      if (!wave.empty()) {
        run_wave(wave);
        if (cancelled()) break;
        wave.clear();
      }
      next_wave(&wave);
      if (wave.empty()) break;
    }
    outcome_.cancelled = cancelled();
    outcome_.cases_planned = progress_.cases_total;
    for (std::size_t i = 0; i < cases_.size(); ++i) {
      if (!planned_[i] || remaining_[i] != 0) continue;
      ++outcome_.cases_finished;
      for (auto& r : records_[i]) outcome_.records.push_back(std::move(*r));
    }
    return std::move(outcome_);
  }

 private:
  bool cancelled() const { return options_.cancel != nullptr && options_.cancel->load(); }

  // Everything checked before any run.
  void validate() const {
    if (options_.threads < 0) throw InvalidArgument("runner: threads must be >= 0");
    for (std::size_t i = 0; i < cases_.size(); ++i) {
      const Case& c = cases_[i];
      if (c.index != i)
        throw InvalidArgument("runner: cases must come from expand_cases() (index mismatch at " +
                              std::to_string(i) + ")");
      if (c.strategies.empty()) {
        throw InvalidArgument("runner: case " + c.id() + " has no strategy");
      }
      for (const std::string& s : c.strategies) {
        // Every setting within its bound before any run (the pipeline validates its table).
        try {
          run_request(config_, s, c.k, options_).resolve(find_preset(s));
        } catch (const InvalidArgument& e) {
          throw InvalidArgument("runner: case " + c.id() + ", " + s + ": " + e.what());
        }
      }
      if (options_.source_covariances_m2 != nullptr &&
          options_.source_covariances_m2->size() != source_points_.size()) {
        throw InvalidArgument("runner: case " + c.id() +
                              ": one source covariance per source point expected");
      }
      if (options_.source_view_directions != nullptr &&
          options_.source_view_directions->size() != source_points_.size()) {
        throw InvalidArgument("runner: case " + c.id() +
                              ": one source viewing direction per source point expected");
      }
      if (!is_finite(c.D))
        throw InvalidArgument("runner: case " + c.id() + " has a non-finite displacement");
    }
    if (options_.history_case && *options_.history_case >= cases_.size()) {
      throw InvalidArgument("runner: history case " + std::to_string(*options_.history_case) +
                            " out of range (" + std::to_string(cases_.size()) + " cases)");
    }
    if (ground_truth_ && !is_finite(*ground_truth_))
      throw InvalidArgument("runner: ground truth is not finite");
  }

  // Records, counts and escalation groups (their cases in level order), indexed by case.
  void bookkeeping() {
    records_.resize(cases_.size());
    remaining_.resize(cases_.size());
    planned_.assign(cases_.size(), true);
    for (std::size_t i = 0; i < cases_.size(); ++i) {
      records_[i].resize(cases_[i].strategies.size());
      remaining_[i] = cases_[i].strategies.size();
    }
    for (const Case& c : cases_) {
      if (c.escalation_group < 0) continue;
      if (static_cast<std::size_t>(c.escalation_group) >= groups_.size())
        groups_.resize(c.escalation_group + 1);
      groups_[c.escalation_group].push_back(c.index);
    }
    for (const Case& c : cases_) progress_.runs_total += c.strategies.size();
    progress_.cases_total = cases_.size();
  }

  // Cases finished by an earlier run: complete, in strategy order.
  void preload() {
    preloaded_.assign(cases_.size(), false);
    for (const RunRecord& r : options_.already_finished) {
      if (r.case_index >= cases_.size())
        throw InvalidArgument("runner: a finished record names case " +
                              std::to_string(r.case_index) + " of " +
                              std::to_string(cases_.size()));
      const Case& c = cases_[r.case_index];
      const std::size_t slot = c.strategies.size() - remaining_[c.index];
      if (remaining_[c.index] == 0 || c.strategies[slot] != r.strategy || r.k != c.k)
        throw InvalidArgument("runner: the finished records of case " + c.id() +
                              " do not match its strategies");
      records_[c.index][slot] = r;
      preloaded_[c.index] = true;
      --remaining_[c.index];
      ++progress_.runs_done;
    }
    for (std::size_t i = 0; i < cases_.size(); ++i) {
      if (!preloaded_[i]) continue;
      if (remaining_[i] != 0)
        throw InvalidArgument("runner: the finished records of case " + cases_[i].id() +
                              " miss strategies");
      ++progress_.cases_done;
    }
  }

  RunRecord run_one(const Task& t) const {
    const Case& c = cases_[t.case_index];
    const std::string& s = c.strategies[t.slot];
    const bool history = options_.history_case && *options_.history_case == c.index;
    // As `lmalign align` runs it: the source displaced by D, its covariances and up axis with
    // it (C' = R_D C R_D^T), the config's k, limits, scale and settings.
    SourceLandmarks undisplaced;
    undisplaced.positions = source_points_;
    if (options_.source_covariances_m2 != nullptr) {
      undisplaced.covariances_m2 = *options_.source_covariances_m2;
    }
    undisplaced.up = options_.source_up;
    if (options_.source_view_directions != nullptr) {
      undisplaced.view_directions = *options_.source_view_directions;
    }
    const SourceLandmarks moved = undisplaced.moved(c.D);
    AlignRequest request = run_request(config_, s, c.k, options_);
    request.record_history = history;
    const Summary summary = align(preset_of_.at(s), moved.view(), target_, request);
    const RegistrationResult& r = summary.registration;
    const PoseCovariance& covariance = summary.covariance;
    RunRecord rec;
    rec.case_index = c.index;
    rec.strategy = s;
    rec.k = c.k;
    rec.initial_score_m2 = r.initial_score_m2;
    rec.final_score_m2 = r.final_score_m2;
    rec.iterations = r.iterations;
    rec.termination = r.termination;
    rec.time_s = r.wall_time_s;
    rec.T_target_source = r.T_target_source;
    // The recovered map-to-map transform T * D against the truth: independent of D.
    if (ground_truth_) rec.error = transform_error(r.T_target_source * c.D, *ground_truth_);
    rec.decision = decide_success(config_.success, rec.error, rec.final_score_m2);
    // A non-finite estimate is never trustworthy.
    if (is_finite(r.T_target_source)) rec.trustworthy = summary.verdict.trustworthy;
    if (covariance.valid) {
      rec.covariance_translation_sd_m = covariance.translation_sd_m();
      rec.covariance_rotation_sd_deg = covariance.rotation_sd_deg();
      // Cov is that of T (left perturbation); T * D = Exp(xi) T_true has the same xi.
      if (ground_truth_ && is_finite(r.T_target_source)) {
        rec.nees = nees(pose_error_twist(r.T_target_source * c.D, *ground_truth_), covariance);
      }
    }
    rec.history = r.history;
    return rec;
  }

  // Whether every target weight of the kind is > 0 (false without such weights: the run itself
  // reports it).
  bool all_positive(WeightKind kind) {
    auto it = positive_weights_.find(kind);
    if (it != positive_weights_.end()) return it->second;
    bool positive = false;
    try {
      const std::vector<double>& w = target_.weights(kind);
      positive = std::all_of(w.begin(), w.end(), [](double x) { return x > 0.0; });
    } catch (const InvalidArgument&) {
    }
    positive_weights_.emplace(kind, positive);
    return positive;
  }

  // Runs with provably identical results (RunnerOptions::share_identical_runs): a key that two
  // runs share only if align() gets the same points and the same correspondence rule. Empty: the
  // run always executes.
  std::string identity_key(const Task& t) {
    const Case& c = cases_[t.case_index];
    const std::string& s = c.strategies[t.slot];
    std::string key;
    if (!options_.share_identical_runs ||
        (options_.history_case && *options_.history_case == c.index)) {
      return key;
    }
    // The points: transform_points(D, source), a function of D's bits.
    key.assign(reinterpret_cast<const char*>(c.D.matrix().data()), 16 * sizeof(double));
    // The pipeline, stage by stage and setting by setting; Eq. 6 with k = 1 keeps the nearest
    // unless its weight is 0 (select_match), so it counts as the nearest neighbour then.
    PipelineSpec spec = resolve_spec(preset_of_.at(s), run_request(config_, s, c.k, options_));
    const Pipeline p(spec);
    if (spec.matcher == "weighted_knn" && p.settings().integer("match.k") == 1 &&
        all_positive(parse_weight_kind(p.settings().choice("match.confidence")))) {
      spec.matcher = "nearest";
      std::vector<std::pair<std::string, SettingValue>> kept;
      for (const auto& kv : spec.settings) {
        if (kv.first != "match.k" && kv.first != "match.confidence") kept.push_back(kv);
      }
      spec.settings = kept;
    }
    const Pipeline q(spec);
    key += "|" + spec.initialiser + "|" + spec.matcher + "|" + spec.kernel + "|" + spec.estimator +
           "|" + spec.schedule + "|" + spec.scorer + "|" + spec.trust;
    for (const std::string& r : spec.rejectors) key += "|" + r;
    key += "|" + q.settings().canonical_text() + "|scale=" + to_string(config_.scale_of(s));
    return key;
  }

  // Stores a finished run's record (under `mutex_`).
  void store(const Task& t, RunRecord rec) {
    records_[t.case_index][t.slot] = std::move(rec);
    ++progress_.runs_done;
    if (--remaining_[t.case_index] == 0) {
      ++progress_.cases_done;
      if (options_.on_case_finished) {
        std::vector<RunRecord> finished;
        for (const auto& r : records_[t.case_index]) finished.push_back(*r);
        options_.on_case_finished(cases_[t.case_index], finished);
      }
    }
    if (options_.on_progress) options_.on_progress(progress_);
  }

  // The tasks in parallel; the first run of each identity key executes, the others take its
  // record. An exception may not leave the parallel loop: the first one stops the remaining runs
  // and is rethrown after it.
  void run_wave(const std::vector<Task>& tasks) {
    std::vector<Task> runs;
    std::vector<std::vector<Task>> copies;  // copies[i]: the tasks that take runs[i]'s record
    std::map<std::string, std::size_t> first_of_key;
    for (const Task& t : tasks) {
      const std::string key = identity_key(t);
      if (!key.empty()) {
        const auto [it, inserted] = first_of_key.emplace(key, runs.size());
        if (!inserted) {
          copies[it->second].push_back(t);
          continue;
        }
      }
      runs.push_back(t);
      copies.emplace_back();
    }
    const SingleLevelParallelism single_level;
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(runs.size());
#pragma omp parallel num_threads(threads_) proc_bind(spread)
    {
      // Inner (ICP) parallel regions of this worker get one thread, even when the team has
      // one thread and is therefore not an active level.
      omp_set_num_threads(1);
#pragma omp for schedule(dynamic, 1)
      for (std::ptrdiff_t i = 0; i < n; ++i) {
        if (error_.failed() || cancelled()) continue;
        const Task& t = runs[static_cast<std::size_t>(i)];
        error_.capture([&] {
          RunRecord rec = run_one(t);
          std::lock_guard<std::mutex> lock(mutex_);
          if (error_.failed()) return;
          for (const Task& u : copies[static_cast<std::size_t>(i)]) {
            // Same D, hence the same error and decision; only the labels differ.
            RunRecord copy = rec;
            copy.case_index = cases_[u.case_index].index;
            copy.strategy = cases_[u.case_index].strategies[u.slot];
            copy.k = cases_[u.case_index].k;
            store(u, std::move(copy));
            ++outcome_.runs_shared;
          }
          store(t, std::move(rec));
        });
      }
    }
    error_.rethrow();
  }

  void add_case(std::vector<Task>* tasks, std::size_t ci) const {
    for (std::size_t s = 0; s < cases_[ci].strategies.size(); ++s) tasks->push_back({ci, s});
  }

  // The escalation groups' next levels: a group goes on only if every strategy succeeded at its
  // last level (stop: all: if any did). A next level finished by an earlier run is taken as it
  // is and the group decided again.
  void next_wave(std::vector<Task>* wave) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t g = 0; g < groups_.size(); ++g) {
      for (;;) {
        const std::size_t level = next_level_[g];
        if (level == 0 || level >= groups_[g].size()) break;
        const std::size_t last = groups_[g][level - 1];
        const bool any_must_succeed =
            config_.experiments[cases_[last].experiment_index].escalation.stop_when_all_fail;
        std::size_t ok = 0;
        for (const auto& r : records_[last]) ok += r && r->decision.success ? 1 : 0;
        const bool go_on =
            remaining_[last] == 0 && (any_must_succeed ? ok > 0 : ok == records_[last].size());
        if (go_on) {
          ++next_level_[g];
          if (preloaded_[groups_[g][level]]) continue;
          add_case(wave, groups_[g][level]);
        } else {
          for (std::size_t l = level; l < groups_[g].size(); ++l) {
            const std::size_t ci = groups_[g][l];
            planned_[ci] = false;
            ++outcome_.cases_skipped;
            progress_.runs_total -= cases_[ci].strategies.size();
            --progress_.cases_total;
          }
          next_level_[g] = 0;  // stopped
          if (options_.on_progress) options_.on_progress(progress_);
        }
        break;
      }
    }
  }

  const ExperimentConfig& config_;
  const std::vector<Case>& cases_;
  const Points3& source_points_;
  const PreparedTarget& target_;
  const std::optional<Isometry3>& ground_truth_;
  const RunnerOptions& options_;
  int threads_ = 1;
  std::vector<std::vector<std::optional<RunRecord>>> records_;
  std::vector<std::size_t> remaining_;
  std::vector<bool> planned_;
  std::vector<bool> preloaded_;
  std::vector<std::vector<std::size_t>> groups_;
  std::vector<std::size_t> next_level_;
  RunnerProgress progress_;
  RunnerOutcome outcome_;
  std::mutex mutex_;
  FirstException error_;
  std::map<std::string, Preset> preset_of_;
  std::map<WeightKind, bool> positive_weights_;
};

}  // namespace

void describe_inputs(const ExperimentInputs& in, SourceDescription& kept, RunnerOptions& options) {
  kept.covariances_m2 = in.source.covariances_m2();
  kept.view_directions = in.source.view_directions();
  options.source_covariances_m2 = &kept.covariances_m2;
  options.source_view_directions = &kept.view_directions;
  options.source_up = estimate_up_axis(in.source);
  options.source_header = in.source.header;
  options.target_header = in.target.header;
}

RunnerOutcome run_cases(const ExperimentConfig& config, const std::vector<Case>& cases,
                        const Points3& source_points, const PreparedTarget& target,
                        const std::optional<Isometry3>& ground_truth,
                        const RunnerOptions& options) {
  return CaseRunner(config, cases, source_points, target, ground_truth, options).run();
}

}  // namespace lmalign
