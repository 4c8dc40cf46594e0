// The report: results.csv schema, summaries (success rate, medians of the successful runs),
// summary.json, and tables.md with the best value of each row in bold.
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lmalign/core/error.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/experiment/report.hpp"
#include "lmalign/experiment/runner.hpp"

namespace lmalign {
namespace {

ExperimentConfig config(bool ground_truth) {
  return parse_experiment_config(
      std::string("source: a.txt\ntarget: b.txt\n") +
          (ground_truth ? "ground_truth: identity\n" : "") +
          "strategies: [base, covariance, observations]\n"
          "experiments:\n"
          "  - {name: ks, type: k, k_values: [1, 5], pose: {y_m: 1}}\n"
          "  - {name: b, type: basin, levels: {yaw_deg: [30]}, samples: 2, yaw_pivot: origin}\n",
      "r.yaml", "/");
}

RunRecord record(std::size_t case_index, const std::string& s, double score, bool success,
                 std::optional<TransformError> error) {
  RunRecord r;
  r.case_index = case_index;
  r.strategy = s;
  r.k = 5;
  r.initial_score_m2 = 0.25;
  r.final_score_m2 = score;
  r.iterations = 40;
  r.termination = TerminationReason::kAbsoluteMse;
  r.time_s = 0.1234567;
  r.error = error;
  r.decision = {success, error ? SuccessCriterion::kGroundTruth : SuccessCriterion::kScore};
  return r;
}

/// Cases 0-1 (ks: k=1, k=5) and 2-3 (basin yaw=30 #0, #1); 3 strategies each.
RunnerOutcome outcome(bool gt) {
  auto e = [&](double rot, double trans) {
    return gt ? std::optional<TransformError>(TransformError{rot, trans}) : std::nullopt;
  };
  RunnerOutcome o;
  o.records = {
      record(0, "base", 0.0081365, true, e(4.63, 0.047)),
      record(0, "covariance", 0.0081365, true, e(4.63, 0.047)),  // tie with base
      record(0, "observations", 0.0081365, true, e(4.63, 0.047)),
      record(1, "base", 0.0081365, true, e(4.63, 0.047)),
      record(1, "covariance", 0.0140339, false, e(15.3, 0.31)),
      record(1, "observations", 0.0082273, true, e(2.51, 0.0471)),
      record(2, "base", 0.02, false, e(30, 0.5)),
      record(2, "covariance", 0.0035, true, e(3, 0.05)),
      record(2, "observations", 0.0036, true, e(2, 0.04)),
      record(3, "base", INFINITY, false, e(90, 2)),
      record(3, "covariance", 0.004, false, e(31, 0.5)),
      record(3, "observations", 0.0036, true, e(2.2, 0.06)),
  };
  o.cases_finished = 4;
  o.cases_planned = 4;
  return o;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> f;
  std::string cell;
  std::stringstream ls(line);
  while (std::getline(ls, cell, ',')) f.push_back(cell);
  if (!line.empty() && line.back() == ',') f.emplace_back();
  return f;
}

TEST(ExperimentReport, ResultsCsvHasTheDocumentedColumns) {
  // docs/experiments.md lists these, in this order.
  const std::string header =
      "experiment,case,label,group,variable,value,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg,"
      "strategy,k,initial_score_m2,final_score_m2,iterations,termination,time_s,"
      "rotation_error_deg,translation_error_m,success,decided_by,trustworthy,nees,"
      "covariance_translation_sd_m,covariance_rotation_sd_deg";
  std::string joined;
  for (const std::string& c : results_csv_columns()) joined += (joined.empty() ? "" : ",") + c;
  EXPECT_EQ(joined, header);

  const ExperimentConfig c = config(true);
  const std::vector<Case> cases = expand_cases(c);
  ASSERT_EQ(cases.size(), 4u);
  std::ostringstream os;
  write_results_csv(os, cases, outcome(true).records);
  std::istringstream in(os.str());
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, header);
  std::vector<std::vector<std::string>> rows;
  while (std::getline(in, line)) rows.push_back(split(line));
  ASSERT_EQ(rows.size(), 12u);
  for (const auto& r : rows) ASSERT_EQ(r.size(), 27u);
  EXPECT_EQ(rows[4], (std::vector<std::string>{"ks",
                                               "1",
                                               "k=5",
                                               "",
                                               "k",
                                               "5",
                                               "0",
                                               "1",
                                               "0",
                                               "0",
                                               "0",
                                               "0",
                                               "covariance",
                                               "5",
                                               "0.25",
                                               "0.0140339",
                                               "40",
                                               "absolute_mse",
                                               "0.123457",
                                               "15.3",
                                               "0.31",
                                               "false",
                                               "ground_truth",
                                               "false",
                                               "",
                                               "",
                                               ""}));
  EXPECT_EQ(rows[9][2], "yaw=30 #1");
  EXPECT_EQ(rows[9][3], "yaw");
  EXPECT_EQ(rows[9][4], "yaw_deg");
  EXPECT_EQ(rows[9][15], "inf");  // a non-finite score is written, never left out

  // Without ground truth the error columns are empty and the score decided.
  std::ostringstream no;
  write_results_csv(no, cases, outcome(false).records);
  std::istringstream in2(no.str());
  std::getline(in2, line);
  std::getline(in2, line);
  const auto r = split(line);
  ASSERT_EQ(r.size(), 27u);
  EXPECT_EQ(r[19], "");
  EXPECT_EQ(r[20], "");
  EXPECT_EQ(r[22], "score");
}

// The trust verdict column (issue 18's benchmark reads it): written per run, read back by
// read_results_csv() (for --resume), and a bad value is refused with its line.
TEST(ExperimentReport, TrustworthyColumnRoundTrips) {
  const ExperimentConfig c = config(true);
  const std::vector<Case> cases = expand_cases(c);
  RunnerOutcome o = outcome(true);
  for (RunRecord& r : o.records) r.k = cases[r.case_index].k;
  o.records[1].trustworthy = true;
  o.records[5].trustworthy = true;
  o.records[2].nees = 7.25;
  o.records[2].covariance_translation_sd_m = 0.0125;
  o.records[2].covariance_rotation_sd_deg = 0.5;
  std::ostringstream os;
  write_results_csv(os, cases, o.records);
  std::istringstream in(os.str());
  const std::vector<RunRecord> back = read_results_csv(in, "results.csv", cases);
  ASSERT_EQ(back.size(), o.records.size());
  for (std::size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back[i].trustworthy, i == 1 || i == 5) << "record " << i;
    // The covariance columns round-trip too (empty = none).
    EXPECT_EQ(back[i].nees, o.records[i].nees) << "record " << i;
    EXPECT_EQ(back[i].covariance_translation_sd_m, o.records[i].covariance_translation_sd_m);
    EXPECT_EQ(back[i].covariance_rotation_sd_deg, o.records[i].covariance_rotation_sd_deg);
  }
  EXPECT_EQ(back[2].nees, std::optional<double>(7.25));

  std::string text = os.str();
  const std::size_t first_row_end = text.find('\n', text.find('\n') + 1);
  ASSERT_EQ(text.substr(first_row_end - 9, 9), ",false,,,");
  text.replace(first_row_end - 8, 5, "maybe");
  std::istringstream bad(text);
  try {
    read_results_csv(bad, "results.csv", cases);
    FAIL() << "accepted trustworthy = maybe";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("results.csv:2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("trustworthy"), std::string::npos) << e.what();
  }
}

TEST(ExperimentReport, SummaryGivesSuccessRatesAndMediansOfTheSuccessfulRuns) {
  EXPECT_TRUE(std::isnan(median({})));
  EXPECT_EQ(median({3, 1, 2}), 2.0);
  EXPECT_EQ(median({4, 1, 2, 3}), 2.5);

  const ExperimentConfig c = config(true);
  const std::vector<Case> cases = expand_cases(c);
  const ReportSummary s = summarize(c, cases, outcome(true));
  EXPECT_TRUE(s.has_ground_truth);
  EXPECT_EQ(s.runs, 12u);
  ASSERT_EQ(s.overall.size(), 3u);
  const StrategySummary& cov = s.overall[1];
  EXPECT_EQ(cov.strategy, "covariance");
  EXPECT_EQ(cov.runs, 4u);
  EXPECT_EQ(cov.successes, 2u);
  EXPECT_EQ(cov.success_rate, 0.5);
  EXPECT_DOUBLE_EQ(cov.median_rotation_error_deg, (4.63 + 3) / 2);  // successful runs only
  EXPECT_DOUBLE_EQ(cov.median_translation_error_m, (0.047 + 0.05) / 2);
  EXPECT_DOUBLE_EQ(cov.median_final_score_m2, (0.004 + 0.0081365) / 2);  // all runs
  ASSERT_EQ(s.experiments.size(), 2u);
  EXPECT_EQ(s.experiments[0].cases, 2u);
  EXPECT_EQ(s.experiments[0].strategies[2].successes, 2u);
  ASSERT_EQ(s.experiments[1].basin_levels.size(), 1u);
  EXPECT_EQ(s.experiments[1].basin_levels[0].level, 30.0);
  EXPECT_EQ(s.experiments[1].basin_levels[0].strategies[0].successes, 0u);
  EXPECT_EQ(s.experiments[1].basin_levels[0].strategies[2].success_rate, 1.0);

  std::ostringstream os;
  write_summary_json(os, c, s);
  const auto j = nlohmann::json::parse(os.str());
  EXPECT_EQ(j["success_criterion"], "ground_truth");
  EXPECT_EQ(j["per_strategy"]["covariance"]["success_rate"], 0.5);
  EXPECT_EQ(j["per_experiment"]["ks"]["per_strategy"]["observations"]["successes"], 2);
  EXPECT_EQ(j["per_experiment"]["b"]["levels"][0]["per_strategy"]["base"]["success_rate"], 0.0);
  EXPECT_TRUE(
      j["per_experiment"]["b"]["per_strategy"]["base"]["median_rotation_error_deg"].is_null());
  EXPECT_FALSE(j["interrupted"].get<bool>());
}

TEST(ExperimentReport, TablesBoldTheBestValueOfEachRow) {
  const ExperimentConfig c = config(true);
  const std::vector<Case> cases = expand_cases(c);
  const RunnerOutcome o = outcome(true);
  std::ostringstream os;
  write_tables_markdown(os, c, cases, o, summarize(c, cases, o));
  const std::string md = os.str();
  // Score row k=1: all equal, so no best.
  EXPECT_NE(md.find("| k=1 | 8.1365 | 8.1365 | 8.1365 |"), std::string::npos) << md;
  // Score row k=5: base lowest; covariance failed (cross).
  EXPECT_NE(md.find("| k=5 | **8.1365** | 14.0339 ✗ | 8.2273 |"), std::string::npos) << md;
  // Rotation row k=5: observations lowest.
  EXPECT_NE(md.find("| k=5 | 4.63 | 15.30 ✗ | **2.51** |"), std::string::npos) << md;
  // Translation (cm) row k=5.
  EXPECT_NE(md.find("| k=5 | **4.7** | 31.0 ✗ | **4.7** |"), std::string::npos) << md;
  // Basin: success rate per level, highest in bold.
  EXPECT_NE(md.find("| yaw 30° | 0/2 (0%) | 1/2 (50%) | **2/2 (100%)** |"), std::string::npos)
      << md;
  // Overview: success rate, highest bold.
  EXPECT_NE(md.find("| **all** | 2/4 (50%) | 2/4 (50%) | **4/4 (100%)** |"), std::string::npos)
      << md;

  // Without ground truth: only the score table, and the criterion is stated.
  const ExperimentConfig n = config(false);
  std::ostringstream ns;
  write_tables_markdown(ns, n, cases, outcome(false), summarize(n, cases, outcome(false)));
  EXPECT_EQ(ns.str().find("Rotation error"), std::string::npos);
  EXPECT_NE(ns.str().find("final score < 0.0037"), std::string::npos);
}

TEST(ExperimentReport, AlignmentPointsHoldTargetInitialAndAlignedClouds) {
  const ExperimentConfig c = config(true);
  const std::vector<Case> cases = expand_cases(c);
  RunRecord r = record(1, "base", 0.01, true, TransformError{0, 0});
  r.T_target_source = cases[1].D.inverse();
  std::ostringstream os;
  write_alignment_points_csv(os, cases[1], {Vec3(1, 2, 3)}, {Vec3(0, 0, 0), Vec3(1, 1, 1)}, {r});
  EXPECT_EQ(os.str(),
            "case,experiment,label,cloud,x,y,z\n"
            "1,ks,k=5,target,0.00000,0.00000,0.00000\n"
            "1,ks,k=5,target,1.00000,1.00000,1.00000\n"
            "1,ks,k=5,initial,1.00000,3.00000,3.00000\n"
            "1,ks,k=5,base,1.00000,2.00000,3.00000\n");
}

}  // namespace
}  // namespace lmalign
