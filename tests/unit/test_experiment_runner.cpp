// The experiment runner on a synthetic pair: success in both modes, errors against the ground
// truth, determinism across thread counts, cancellation, escalation, per-case history.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/experiment/report.hpp"
#include "lmalign/experiment/runner.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

// Source = 2/3 of the target's landmarks, in a frame moved by T_true^-1.
struct Pair {
  Map target_map;
  Points3 source;
  Isometry3 T_true;
};

const Pair& pair() {
  static const Pair p = [] {
    Pair q;
    const Points3 pts = test::room_points(1200, 11);
    q.target_map = test::map_from_points(pts, 12);
    q.T_true = pose_from_xyz_rpy_deg(0.05, -0.03, 0.02, 1, -1, 3);
    q.source = transform_points(q.T_true.inverse(), Points3(pts.begin(), pts.begin() + 800));
    return q;
  }();
  return p;
}

const PreparedTarget& target() {
  static const PreparedTarget t(pair().target_map);
  return t;
}

ExperimentConfig config(const std::string& experiments, const std::string& extra = "") {
  return parse_experiment_config(
      "source: a.txt\ntarget: b.txt\nstrategies: [base, observations]\n" + extra +
          "experiments:\n" + experiments,
      "t.yaml", "/");
}

const std::string kExperiments =
    "  - {name: ks, type: k, k_values: [1, 5], pose: {x_m: 0.1, yaw_deg: 5}}\n"
    "  - {name: yaws, type: yaw, yaw_deg: [0, 10, 120, 170]}\n"
    "  - {name: bas, type: basin, levels: {yaw_deg: [20], translation_m: [0.3]}, samples: 2}\n";

std::string csv_of(const std::vector<Case>& cases, const std::vector<RunRecord>& records) {
  std::ostringstream os;
  write_results_csv(os, cases, records);
  return os.str();
}

/// results.csv without its time_s column.
std::string without_time(const std::string& csv) {
  std::istringstream in(csv);
  std::string line, out;
  const auto& cols = results_csv_columns();
  const std::size_t t = std::find(cols.begin(), cols.end(), "time_s") - cols.begin();
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ',')) f.push_back(cell);
    if (line.back() == ',') f.emplace_back();
    EXPECT_EQ(f.size(), cols.size()) << line;
    if (t < f.size()) f.erase(f.begin() + static_cast<std::ptrdiff_t>(t));
    for (const std::string& x : f) out += x + ",";
    out += "\n";
  }
  return out;
}

TEST(ExperimentSuccess, GroundTruthDecidesWhenKnownElseTheScore) {
  SuccessCriteria c;  // 5 deg, 0.10 m, 0.0037 m^2
  auto gt = [&](double rot, double trans, double score) {
    return decide_success(c, TransformError{rot, trans}, score);
  };
  EXPECT_TRUE(gt(4.9, 0.099, 1.0).success);  // the score is ignored with ground truth
  EXPECT_EQ(gt(4.9, 0.099, 1.0).decided_by, SuccessCriterion::kGroundTruth);
  EXPECT_FALSE(gt(5.0, 0.01, 0.0).success);  // strict <
  EXPECT_FALSE(gt(1.0, 0.10, 0.0).success);
  EXPECT_FALSE(gt(NAN, 0.01, 0.0).success);
  EXPECT_TRUE(decide_success(c, std::nullopt, 0.0036).success);
  EXPECT_EQ(decide_success(c, std::nullopt, 0.0036).decided_by, SuccessCriterion::kScore);
  EXPECT_FALSE(decide_success(c, std::nullopt, 0.0037).success);
  EXPECT_FALSE(decide_success(c, std::nullopt, INFINITY).success);
  c.rotation_deg = 10;
  c.translation_m = 0.5;
  c.score_m2 = 0.01;
  EXPECT_TRUE(gt(9.0, 0.4, 1.0).success);  // thresholds are configurable
  EXPECT_TRUE(decide_success(c, std::nullopt, 0.009).success);
  EXPECT_EQ(to_string(SuccessCriterion::kGroundTruth), "ground_truth");
  EXPECT_EQ(to_string(SuccessCriterion::kScore), "score");
}

TEST(ExperimentRunner, ErrorsAreOfTheRecoveredMapTransformAndDecideSuccess) {
  const ExperimentConfig c = config(kExperiments);
  const std::vector<Case> cases = expand_cases(c, pair().source);
  const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true);
  ASSERT_EQ(o.cases_finished, cases.size());
  ASSERT_EQ(o.records.size(), 2 * cases.size());
  EXPECT_FALSE(o.cancelled);
  std::size_t successes = 0, failures = 0;
  for (const RunRecord& r : o.records) {
    const Case& cs = cases[r.case_index];
    SCOPED_TRACE(cs.id() + " " + r.strategy);
    ASSERT_TRUE(r.error.has_value());
    EXPECT_EQ(r.decision.decided_by, SuccessCriterion::kGroundTruth);
    // The error is that of T_est * D against the truth, not of T_est against D^-1 T_true.
    const TransformError e = transform_error(r.T_target_source * cs.D, pair().T_true);
    EXPECT_EQ(e.rotation_deg, r.error->rotation_deg);
    EXPECT_EQ(r.decision.success, e.rotation_deg < 5.0 && e.translation_m < 0.10);
    if (cs.value <= 20 || cs.variable == "translation_m" || cs.variable == "k") {
      // Small displacements of an exact subset: the right basin, and base finds the exact
      // answer (the weighted strategies may pick a farther, heavier candidate).
      EXPECT_TRUE(r.decision.success);
      if (r.strategy == "base") {
        EXPECT_LT(r.error->rotation_deg, 1e-5);
        EXPECT_LT(r.error->translation_m, 1e-6);
      }
    }
    (r.decision.success ? successes : failures)++;
    EXPECT_EQ(r.k, cs.k);
    EXPECT_GT(r.iterations, 0);
  }
  EXPECT_GT(failures, 0u) << "yaw 120/170 should leave the basin";
  // k = 1 is the base strategy exactly (method.md §3).
  EXPECT_EQ(o.records[0].final_score_m2, o.records[1].final_score_m2);
  EXPECT_TRUE(o.records[0].T_target_source.isApprox(o.records[1].T_target_source, 0.0));

  // Without ground truth the score decides, and there are no errors.
  const RunnerOutcome n = run_cases(c, cases, pair().source, target(), std::nullopt);
  for (std::size_t i = 0; i < n.records.size(); ++i) {
    EXPECT_FALSE(n.records[i].error.has_value());
    EXPECT_EQ(n.records[i].decision.decided_by, SuccessCriterion::kScore);
    EXPECT_EQ(n.records[i].decision.success, n.records[i].final_score_m2 < 0.0037);
    EXPECT_EQ(n.records[i].final_score_m2, o.records[i].final_score_m2);
  }
}

TEST(ExperimentRunner, OutputIsIdenticalForAnyThreadCountApartFromTime) {
  const ExperimentConfig c = config(kExperiments);
  const std::vector<Case> cases = expand_cases(c, pair().source);
  std::vector<std::string> csvs;
  for (int threads : {1, 2, 3}) {
    RunnerOptions opt;
    opt.threads = threads;
    const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
    csvs.push_back(csv_of(cases, o.records));
  }
  const std::string ref = without_time(csvs[0]);
  EXPECT_EQ(std::count(ref.begin(), ref.end(), '\n'), 1 + 2 * static_cast<long>(cases.size()));
  for (const std::string& csv : csvs) EXPECT_EQ(without_time(csv), ref);
}

TEST(ExperimentRunner, IdenticalRunsRunOnceAndGiveTheRecordsOfRunningThemAll) {
  // Base ignores k, and observations with k = 1 picks the nearest while every weight is
  // positive: of these 6 runs, base at k = 5 and 7 and observations at k = 1 are base at k = 1.
  const ExperimentConfig c =
      config("  - {name: ks, type: k, k_values: [1, 5, 7], pose: {x_m: 0.1, yaw_deg: 5}}\n");
  const std::vector<Case> cases = expand_cases(c, pair().source);
  ASSERT_EQ(cases.size(), 3u);
  RunnerOptions every;
  every.share_identical_runs = false;
  const RunnerOutcome all = run_cases(c, cases, pair().source, target(), pair().T_true, every);
  const RunnerOutcome shared = run_cases(c, cases, pair().source, target(), pair().T_true);
  EXPECT_EQ(all.runs_shared, 0u);
  EXPECT_EQ(shared.runs_shared, 3u);
  ASSERT_EQ(shared.records.size(), 6u);
  EXPECT_EQ(without_time(csv_of(cases, shared.records)), without_time(csv_of(cases, all.records)));
  // Not vacuous: observations at k = 5 is another run, with other results.
  const auto record = [&](const RunnerOutcome& o, std::size_t ci, std::string s) {
    for (const RunRecord& r : o.records) {
      if (r.case_index == ci && r.strategy == s) return r;
    }
    ADD_FAILURE() << "no record";
    return RunRecord{};
  };
  EXPECT_NE(record(all, 1, "observations").T_target_source.matrix(),
            record(all, 1, "base").T_target_source.matrix());
  // A copy carries the time of the run it copies, and its own labels.
  const RunRecord copy = record(shared, 2, "base");
  EXPECT_EQ(copy.time_s, record(shared, 0, "base").time_s);
  EXPECT_EQ(copy.k, 7);

  // The history case always runs (it records what a copy would not have).
  RunnerOptions history;
  history.history_case = 1;
  const RunnerOutcome h = run_cases(c, cases, pair().source, target(), pair().T_true, history);
  EXPECT_EQ(h.runs_shared, 2u);
  EXPECT_EQ(record(h, 1, "base").history.size(),
            static_cast<std::size_t>(record(h, 1, "base").iterations));

  // With a zero weight, Eq. 6 at k = 1 leaves that landmark unmatched: observations at k = 1 is
  // no longer base, and runs.
  PreparedTarget zero(pair().target_map);
  std::vector<double> w = zero.weights(WeightKind::kObservations);
  w[0] = 0.0;
  zero.set_weights(WeightKind::kObservations, w);
  const RunnerOutcome z = run_cases(c, cases, pair().source, zero, pair().T_true);
  const RunnerOutcome z_all = run_cases(c, cases, pair().source, zero, pair().T_true, every);
  EXPECT_EQ(z.runs_shared, 2u);
  EXPECT_EQ(without_time(csv_of(cases, z.records)), without_time(csv_of(cases, z_all.records)));
}

TEST(ExperimentRunner, CancellingLeavesExactlyTheFinishedCasesInTheCsv) {
  const ExperimentConfig c = config(kExperiments);
  const std::vector<Case> cases = expand_cases(c, pair().source);
  for (int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    std::atomic<bool> cancel{false};
    std::map<std::size_t, std::vector<RunRecord>> done;
    std::string flushed;
    std::size_t progress_calls = 0;
    RunnerOptions opt;
    opt.threads = threads;
    opt.cancel = &cancel;
    opt.on_progress = [&](const RunnerProgress& p) {
      ++progress_calls;
      EXPECT_LE(p.runs_done, p.runs_total);
    };
    opt.on_case_finished = [&](const Case& cs, const std::vector<RunRecord>& recs) {
      EXPECT_EQ(recs.size(), cs.strategies.size());
      done[cs.index] = recs;
      std::vector<RunRecord> rows;
      for (const auto& [i, r] : done) rows.insert(rows.end(), r.begin(), r.end());
      flushed = csv_of(cases, rows);  // what the CLI writes to results.csv
      if (done.size() == 3) cancel.store(true);
    };
    const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
    EXPECT_TRUE(o.cancelled);
    EXPECT_EQ(o.cases_finished, done.size());
    EXPECT_GE(o.cases_finished, 3u);
    EXPECT_LT(o.cases_finished, cases.size());
    if (threads == 1) EXPECT_EQ(o.cases_finished, 3u);  // nothing else was in flight
    EXPECT_EQ(o.records.size(), 2 * o.cases_finished);
    EXPECT_GE(progress_calls, o.records.size());
    // The last flushed CSV is the final one: header + every row of the finished cases.
    EXPECT_EQ(flushed, csv_of(cases, o.records));
    EXPECT_EQ(std::count(flushed.begin(), flushed.end(), '\n'),
              1 + 2 * static_cast<long>(o.cases_finished));
    without_time(flushed);  // checks every row has every column
  }
}

TEST(ExperimentRunner, EscalationStopsAQuadrantAtItsFirstFailure) {
  // With a 45 deg yaw, in -X-Y base fails from 1 m on while observations still succeeds; in +X+Y
  // both succeed up to 2 m. "full" runs every offset, to check the escalations against.
  const ExperimentConfig c = config(
      "  - {name: esc, type: xy, escalate: {start_m: 0.5, step_m: 0.5, max_m: 2}, quadrants: "
      "[-X-Y, +X+Y], pose: {yaw_deg: 45}}\n"
      "  - {name: all, type: xy, escalate: {start_m: 0.5, step_m: 0.5, max_m: 2, stop: all}, "
      "quadrants: [-X-Y], pose: {yaw_deg: 45}}\n"
      "  - {name: full, type: xy, offsets_m: {-X-Y: [0.5, 1, 1.5, 2], +X+Y: [0.5, 1, 1.5, 2]}, "
      "pose: {yaw_deg: 45}}\n",
      "max_iterations: 60\n");
  const std::vector<Case> cases = expand_cases(c);
  ASSERT_EQ(cases.size(), 20u);  // 2 x 4 + 4 + 2 x 4
  std::size_t finished_callbacks = 0;
  RunnerOptions opt;
  opt.on_case_finished = [&](const Case&, const std::vector<RunRecord>&) { ++finished_callbacks; };
  const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
  EXPECT_EQ(finished_callbacks, o.cases_finished);
  // Per quadrant and offset of "full": did every strategy succeed, did any?
  std::map<std::string, std::map<double, bool>> all_ok, any_ok;
  std::map<std::string, std::vector<double>> ran;
  for (const RunRecord& r : o.records) {
    const Case& cs = cases[r.case_index];
    if (cs.experiment == "full") {
      all_ok[cs.group].emplace(cs.value, true).first->second &= r.decision.success;
      any_ok[cs.group].emplace(cs.value, false).first->second |= r.decision.success;
    } else if (r.strategy == "base") {
      ran[cs.experiment + cs.group].push_back(cs.value);
    }
  }
  // Levels an escalation runs: up to and including the first at which it must stop.
  auto expected_levels = [&](const std::map<double, bool>& go_on) {
    std::vector<double> v;
    for (const auto& [level, ok] : go_on) {
      v.push_back(level);
      if (!ok) break;
    }
    return v;
  };
  EXPECT_EQ(ran["esc-X-Y"], expected_levels(all_ok["-X-Y"]));
  EXPECT_EQ(ran["esc+X+Y"], expected_levels(all_ok["+X+Y"]));
  EXPECT_EQ(ran["all-X-Y"], expected_levels(any_ok["-X-Y"]));
  EXPECT_LT(ran["esc-X-Y"].size(), 4u) << "the scene should make base fail in -X-Y";
  EXPECT_GT(ran["all-X-Y"].size(), ran["esc-X-Y"].size()) << "observations should go further";
  EXPECT_EQ(o.cases_skipped + o.cases_finished, cases.size());
  EXPECT_EQ(o.cases_planned, o.cases_finished);

  // Deterministic: the same again with another thread count.
  opt.threads = 1;
  const RunnerOutcome again = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
  EXPECT_EQ(without_time(csv_of(cases, again.records)), without_time(csv_of(cases, o.records)));
}

TEST(ExperimentRunner, ResumingFromTheCsvOfAnInterruptedRunFinishesTheRestOnly) {
  // Escalations (decided again from records read back) and plain cases.
  const ExperimentConfig c = config(
      "  - {name: esc, type: xy, escalate: {start_m: 0.5, step_m: 0.5, max_m: 2}, quadrants: "
      "[-X-Y, +X+Y], pose: {yaw_deg: 45}}\n"
      "  - {name: yaws, type: yaw, yaw_deg: [0, 10, 120]}\n",
      "max_iterations: 60\n");
  const std::vector<Case> cases = expand_cases(c);
  const RunnerOutcome full = run_cases(c, cases, pair().source, target(), pair().T_true);
  const std::string full_csv = csv_of(cases, full.records);
  ASSERT_GE(full.cases_finished, 6u);

  // Every prefix of finished cases (what an interrupted run leaves), read back from its CSV.
  std::vector<std::size_t> finished_cases;
  for (const RunRecord& r : full.records) {
    if (finished_cases.empty() || finished_cases.back() != r.case_index)
      finished_cases.push_back(r.case_index);
  }
  for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{3}, finished_cases.size()}) {
    std::vector<RunRecord> done;
    for (const RunRecord& r : full.records) {
      if (std::find(finished_cases.begin(), finished_cases.begin() + n, r.case_index) !=
          finished_cases.begin() + n)
        done.push_back(r);
    }
    std::istringstream partial(csv_of(cases, done));
    RunnerOptions opt;
    opt.already_finished = read_results_csv(partial, "results.csv", cases);
    ASSERT_EQ(opt.already_finished.size(), done.size());
    std::size_t ran = 0;
    opt.on_case_finished = [&](const Case& cs, const std::vector<RunRecord>&) {
      ++ran;
      EXPECT_EQ(std::find(finished_cases.begin(), finished_cases.begin() + n, cs.index),
                finished_cases.begin() + n)
          << "case " << cs.id() << " was finished already";
    };
    const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
    EXPECT_EQ(ran, finished_cases.size() - n) << n;
    EXPECT_EQ(o.cases_finished, full.cases_finished);
    EXPECT_EQ(o.cases_skipped, full.cases_skipped);
    EXPECT_EQ(without_time(csv_of(cases, o.records)), without_time(full_csv)) << n;
    // The records read back write the same text, wall time included.
    EXPECT_EQ(csv_of(cases, opt.already_finished), csv_of(cases, done));
  }

  // Incomplete or foreign records are refused.
  RunnerOptions half;
  half.already_finished = {full.records[0]};
  EXPECT_THROW(run_cases(c, cases, pair().source, target(), pair().T_true, half), InvalidArgument);
}

TEST(ExperimentReport, ReadingResultsCsvIsStrict) {
  const ExperimentConfig c = config(kExperiments);
  const std::vector<Case> cases = expand_cases(c, pair().source);
  const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true);
  const std::string csv = csv_of(cases, o.records);
  auto read = [&](const std::string& text) {
    std::istringstream in(text);
    return read_results_csv(in, "r.csv", cases);
  };
  EXPECT_EQ(csv_of(cases, read(csv)), csv);
  const std::size_t first_row = csv.find('\n') + 1;
  const std::size_t second_row = csv.find('\n', first_row) + 1;
  const std::size_t third_row = csv.find('\n', second_row) + 1;
  // Half a case, a half-written line, a foreign header, a changed label: ParseError with a line.
  EXPECT_THROW(read(csv.substr(0, second_row)), ParseError);
  EXPECT_THROW(read(csv.substr(0, third_row - 1)), ParseError);
  EXPECT_THROW(read("case,x\n"), ParseError);
  EXPECT_THROW(read(""), ParseError);
  std::string relabelled = csv;
  relabelled.replace(relabelled.find(",k=1,"), 5, ",k=2,");
  try {
    read(relabelled);
    ADD_FAILURE() << "a foreign label was accepted";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 2u);
    EXPECT_NE(e.detail().find("label 'k=2' differs from case ks/k=1"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read(csv.substr(0, first_row)).size(), 0u);  // header only: nothing finished
}

TEST(ExperimentRunner, RecordsHistoryForTheChosenCaseOnly) {
  const ExperimentConfig c = config(kExperiments);
  const std::vector<Case> cases = expand_cases(c, pair().source);
  RunnerOptions opt;
  opt.history_case = 3;
  const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
  for (const RunRecord& r : o.records) {
    if (r.case_index == 3) {
      ASSERT_EQ(r.history.size(), static_cast<std::size_t>(r.iterations));
      EXPECT_TRUE(std::isfinite(r.history.back().score_m2));
      EXPECT_DOUBLE_EQ(r.history.back().score_m2, r.final_score_m2);
    } else {
      EXPECT_TRUE(r.history.empty());
    }
  }
  std::ostringstream h;
  std::vector<RunRecord> of3;
  for (const RunRecord& r : o.records) {
    if (r.case_index == 3) of3.push_back(r);
  }
  write_history_csv(h, cases[3], of3);
  const std::string text = h.str();
  EXPECT_EQ(
      text.rfind("case,experiment,label,strategy,iteration,num_correspondences,mse_m2,score_m2\n",
                 0),
      0u);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1 + of3[0].iterations + of3[1].iterations);
}

TEST(ExperimentRunner, CallbackExceptionsAndBadSettingsPropagate) {
  const ExperimentConfig c = config(kExperiments);
  const std::vector<Case> cases = expand_cases(c, pair().source);
  RunnerOptions opt;
  opt.on_case_finished = [](const Case&, const std::vector<RunRecord>&) {
    throw IoError("disk full");
  };
  EXPECT_THROW(run_cases(c, cases, pair().source, target(), pair().T_true, opt), IoError);
  RunnerOptions bad;
  bad.history_case = cases.size();
  EXPECT_THROW(run_cases(c, cases, pair().source, target(), pair().T_true, bad), InvalidArgument);
  std::vector<Case> shuffled = cases;
  std::swap(shuffled[0], shuffled[1]);
  EXPECT_THROW(run_cases(c, shuffled, pair().source, target(), pair().T_true), InvalidArgument);
}

}  // namespace
}  // namespace lmalign

namespace lmalign {
namespace {

TEST(ExperimentRunner, PresetsRunWithTheSourceCovariancesAndTheConfigsSettingsAndLimits) {
  ExperimentConfig c =
      config("  - {name: yaws, type: yaw, yaw_deg: [0, 10], strategies: [robust_obs, adaptive]}\n");
  c.settings = {{"adaptive", {{"score.samples", 256LL}}}};
  const std::vector<Case> cases = expand_cases(c, pair().source);
  // The source's covariances: the target map's first 800, in the source frame.
  std::vector<Mat3> cov;
  const Mat3 R = pair().T_true.linear();
  for (std::size_t i = 0; i < pair().source.size(); ++i) {
    cov.push_back(R.transpose() * pair().target_map.landmarks[i].cov_world_m2 * R);
  }
  RunnerOptions opt;
  opt.threads = 1;
  opt.source_covariances_m2 = &cov;
  const RunnerOutcome o = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
  ASSERT_EQ(o.records.size(), 4u);
  for (const RunRecord& r : o.records) {
    ASSERT_TRUE(r.error.has_value());
    EXPECT_LT(r.error->rotation_deg, 0.01) << r.strategy;
    EXPECT_LT(r.error->translation_m, 1e-3) << r.strategy;
    EXPECT_TRUE(r.covariance_translation_sd_m.has_value()) << r.strategy;
  }
  // The request is the CLI's: the config's settings for that strategy, its limits when given.
  EXPECT_EQ(run_request(c, "adaptive", 5).settings.size(), 1u);
  EXPECT_TRUE(run_request(c, "robust_obs", 5).settings.empty());
  EXPECT_FALSE(run_request(c, "robust_obs", 5).max_iterations.has_value());
  c.max_iterations = 2;
  const RunnerOutcome capped = run_cases(c, cases, pair().source, target(), pair().T_true, opt);
  for (const RunRecord& r : capped.records) {
    if (r.strategy == "robust_obs") EXPECT_LE(r.iterations, 2);
  }
  // A setting out of its bound is refused before any run.
  c.settings = {{"adaptive", {{"score.samples", 3LL}}}};
  EXPECT_THROW(run_cases(c, cases, pair().source, target(), pair().T_true, opt), InvalidArgument);
  const std::vector<Mat3> few(3, Mat3::Identity());
  c.settings.clear();
  opt.source_covariances_m2 = &few;
  EXPECT_THROW(run_cases(c, cases, pair().source, target(), pair().T_true, opt), InvalidArgument);
}

TEST(ExperimentRunner, ScaleFreeRecoversAScaledSourceWhereFixedCannot) {
  // The source: the target's landmarks shrunk by 0.8 about the origin (a map with its own scale).
  const Points3 pts = test::room_points(1200, 11);
  const Map target_map = test::map_from_points(pts, 12);
  const PreparedTarget target(target_map);
  Points3 source;
  for (const Vec3& p : pts) source.push_back(0.8 * p);
  const auto run = [&](const std::string& scale, MapScale source_scale = MapScale::kMetric) {
    const ExperimentConfig c = config(
        "  - {name: e, type: yaw, yaw_deg: [0], strategies: [base]}\n", "scale: " + scale + "\n");
    RunnerOptions opt;
    opt.threads = 1;
    opt.source_header.scale = source_scale;
    const RunnerOutcome o =
        run_cases(c, expand_cases(c, source), source, target, Isometry3::Identity(), opt);
    EXPECT_EQ(o.records.size(), 1u);
    return o.records.at(0);
  };
  const RunRecord free = run("free");
  const RunRecord fixed = run("fixed");
  EXPECT_LT(free.final_score_m2, 1e-6);
  EXPECT_GT(fixed.final_score_m2, 100 * free.final_score_m2);
  // auto follows the maps' headers (RunnerOptions::source_header): rigid for metric maps, a
  // similarity when the source's scale is arbitrary.
  EXPECT_EQ(run("auto").final_score_m2, fixed.final_score_m2);
  EXPECT_EQ(run("auto", MapScale::kArbitrary).final_score_m2, free.final_score_m2);
}

}  // namespace
}  // namespace lmalign
