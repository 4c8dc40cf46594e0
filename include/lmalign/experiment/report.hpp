// The report of an experiment run (docs/experiments.md, "Output"): results.csv, summary.json,
// tables.md, and the per-case files the plotting script reads. Functions here produce text on a
// stream; the caller writes each file atomically (write_output()).
#pragma once

#include <cstddef>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/experiment/runner.hpp"

namespace lmalign {

/// The columns of results.csv, in order:
/// experiment, case, label, group, variable, value, x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg,
/// strategy, k, initial_score_m2, final_score_m2, iterations, termination, time_s,
/// rotation_error_deg, translation_error_m, success, decided_by.
const std::vector<std::string>& results_csv_columns();

/// Writes the header and one row per record, in the order given. Numbers use the shortest text
/// that reads back exactly (time_s: microseconds); errors are empty without ground truth, and a
/// non-finite score is written "inf". Labels never contain commas or quotes.
void write_results_csv(std::ostream& out, const std::vector<Case>& cases,
                       const std::vector<RunRecord>& records);

/// Reads back a results.csv written by write_results_csv() for the same `cases` (the finished
/// cases of an interrupted run, for `lmalign experiment --resume`). Every row must name a case of
/// `cases` with its experiment, label, displacement, k and one of its strategies, and every case
/// present must have all its strategies in order; write_results_csv() of the result gives back
/// the same text. The records carry no transform and no history (results.csv has neither).
/// Throws ParseError("<file>:<line>: ...") on anything else; `file` only names the source.
std::vector<RunRecord> read_results_csv(std::istream& in, const std::string& file,
                                        const std::vector<Case>& cases);

/// Success rate and medians of one strategy over a set of runs.
struct StrategySummary {
  std::string strategy;  ///< the preset's name
  std::size_t runs = 0;
  std::size_t successes = 0;
  double success_rate = 0.0;  ///< successes / runs (0 if no runs)
  /// Medians over the successful runs (NaN if none, or no ground truth for the errors).
  double median_rotation_error_deg = std::numeric_limits<double>::quiet_NaN();
  double median_translation_error_m = std::numeric_limits<double>::quiet_NaN();
  double median_final_score_successful_m2 = std::numeric_limits<double>::quiet_NaN();
  /// Medians over all runs.
  double median_final_score_m2 = std::numeric_limits<double>::quiet_NaN();
  double median_iterations = std::numeric_limits<double>::quiet_NaN();
  double median_time_s = std::numeric_limits<double>::quiet_NaN();
};

/// Success counts of one basin level.
struct BasinLevelSummary {
  std::string axis;  ///< "yaw" or "translation"
  double level = 0.0;
  std::vector<StrategySummary> strategies;
};

struct ExperimentSummary {
  std::string name;
  ExperimentType type = ExperimentType::kPoses;
  std::size_t cases = 0;  ///< finished cases
  std::vector<StrategySummary> strategies;
  std::vector<BasinLevelSummary> basin_levels;  ///< basin experiments only
};

struct ReportSummary {
  bool has_ground_truth = false;
  bool interrupted = false;
  std::size_t cases_planned = 0;
  std::size_t cases_finished = 0;
  std::size_t cases_skipped = 0;
  std::size_t runs = 0;
  /// Over every finished run, per strategy (in the config's strategy order, then any other).
  std::vector<StrategySummary> overall;
  std::vector<ExperimentSummary> experiments;
};

/// Median of `values` (mean of the two middle ones for an even count); NaN if empty.
double median(std::vector<double> values);

ReportSummary summarize(const ExperimentConfig& config, const std::vector<Case>& cases,
                        const RunnerOutcome& outcome);

/// summary.json: the settings, and success rate and medians per strategy and per experiment
/// (basin: per level). Non-finite numbers are null.
void write_summary_json(std::ostream& out, const ExperimentConfig& config,
                        const ReportSummary& summary);

/// tables.md: paper-style tables. Per experiment: the final score (x 10^-3 m^2) and, with ground
/// truth, the rotation (deg) and translation (cm) errors, one row per case and one column per
/// strategy, the best (lowest) value of each row in bold (all of them on a tie; none if the whole
/// row is equal) and failed runs marked with a cross; basin experiments: the success rate per
/// level, the best (highest) in bold. Also an overview of success rates and median errors.
void write_tables_markdown(std::ostream& out, const ExperimentConfig& config,
                           const std::vector<Case>& cases, const RunnerOutcome& outcome,
                           const ReportSummary& summary);

/// history.csv for one case: case, experiment, label, strategy, iteration, num_correspondences,
/// mse_m2, score_m2 (the score after each iteration), one row per iteration of every record.
void write_history_csv(std::ostream& out, const Case& c, const std::vector<RunRecord>& records);

/// alignment_points.csv for one case: case, experiment, label, cloud, x, y, z (target frame,
/// metres), where
/// cloud is "target", "initial" (the displaced source) or a strategy name (the aligned source).
void write_alignment_points_csv(std::ostream& out, const Case& c, const Points3& source_points,
                                const Points3& target_points,
                                const std::vector<RunRecord>& records);

}  // namespace lmalign
