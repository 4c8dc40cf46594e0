// results.csv, summary.json, tables.md and the per-case plot inputs (docs/experiments.md,
// "Output"). Everything but time_s / median_time_s is a function of the results alone, so two
// runs write identical files apart from those.
#include "lmalign/experiment/report.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <istream>
#include <map>
#include <optional>
#include <ostream>
#include <system_error>

#include <nlohmann/json.hpp>

#include "lmalign/core/error.hpp"
#include "text_format.hpp"

namespace lmalign {

namespace {

using detail::shortest;

const std::vector<std::string> kColumns{"experiment",
                                        "case",
                                        "label",
                                        "group",
                                        "variable",
                                        "value",
                                        "x_m",
                                        "y_m",
                                        "z_m",
                                        "roll_deg",
                                        "pitch_deg",
                                        "yaw_deg",
                                        "strategy",
                                        "k",
                                        "initial_score_m2",
                                        "final_score_m2",
                                        "iterations",
                                        "termination",
                                        "time_s",
                                        "rotation_error_deg",
                                        "translation_error_m",
                                        "success",
                                        "decided_by",
                                        "trustworthy",
                                        "nees",
                                        "covariance_translation_sd_m",
                                        "covariance_rotation_sd_deg"};

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s[0] == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);  // "-0.00"
  return s;
}

nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

StrategySummary summarize_runs(const std::string& s, const std::vector<const RunRecord*>& runs) {
  StrategySummary out;
  out.strategy = s;
  std::vector<double> rot, trans, score_ok, score, iters, times;
  for (const RunRecord* r : runs) {
    ++out.runs;
    score.push_back(r->final_score_m2);
    iters.push_back(r->iterations);
    times.push_back(r->time_s);
    if (r->decision.success) {
      ++out.successes;
      score_ok.push_back(r->final_score_m2);
      if (r->error) {
        rot.push_back(r->error->rotation_deg);
        trans.push_back(r->error->translation_m);
      }
    }
  }
  out.success_rate = out.runs > 0 ? static_cast<double>(out.successes) / out.runs : 0.0;
  out.median_rotation_error_deg = median(rot);
  out.median_translation_error_m = median(trans);
  out.median_final_score_successful_m2 = median(score_ok);
  out.median_final_score_m2 = median(score);
  out.median_iterations = median(iters);
  out.median_time_s = median(times);
  return out;
}

/// Strategies in first-seen order over `order`, then any others found in `records`.
std::vector<std::string> strategy_order(const std::vector<std::string>& order,
                                        const std::vector<const RunRecord*>& records) {
  std::vector<std::string> out = order;
  for (const RunRecord* r : records) {
    if (std::find(out.begin(), out.end(), r->strategy) == out.end()) out.push_back(r->strategy);
  }
  return out;
}

std::vector<StrategySummary> summarize_by_strategy(const std::vector<std::string>& order,
                                                   const std::vector<const RunRecord*>& records) {
  std::vector<StrategySummary> out;
  for (const std::string& s : strategy_order(order, records)) {
    std::vector<const RunRecord*> mine;
    for (const RunRecord* r : records) {
      if (r->strategy == s) mine.push_back(r);
    }
    if (!mine.empty()) out.push_back(summarize_runs(s, mine));
  }
  return out;
}

nlohmann::json strategy_json(const StrategySummary& s, bool with_time) {
  nlohmann::json j;
  j["runs"] = s.runs;
  j["successes"] = s.successes;
  j["success_rate"] = s.success_rate;
  j["median_rotation_error_deg"] = num(s.median_rotation_error_deg);
  j["median_translation_error_m"] = num(s.median_translation_error_m);
  j["median_final_score_successful_m2"] = num(s.median_final_score_successful_m2);
  j["median_final_score_m2"] = num(s.median_final_score_m2);
  j["median_iterations"] = num(s.median_iterations);
  if (with_time) j["median_time_s"] = num(s.median_time_s);
  return j;
}

// --- markdown helpers

std::string md_row(const std::vector<std::string>& cells) {
  std::string s = "|";
  for (const std::string& c : cells) s += " " + c + " |";
  return s + "\n";
}

std::string md_rule(std::size_t n) {
  std::string s = "|";
  for (std::size_t i = 0; i < n; ++i) s += i == 0 ? "---|" : "---:|";
  return s + "\n";
}

/// Cells of one row: the display text of each value, the best bold (lowest, or highest with
/// `higher_is_better`), compared on the displayed rounding so that ties are all bold; a row whose
/// values all display the same has no best and no bold. A cell with no value shows "–"; `marks`
/// are appended after the (possibly bold) value.
std::vector<std::string> bold_best(const std::vector<std::optional<double>>& values,
                                   const std::vector<std::string>& texts,
                                   const std::vector<std::string>& marks, bool higher_is_better) {
  constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  std::size_t best = kNone;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!values[i] || !std::isfinite(*values[i])) continue;
    if (best == kNone ||
        (higher_is_better ? *values[i] > *values[best] : *values[i] < *values[best])) {
      best = i;
    }
  }
  std::size_t shown = 0, same_as_best = 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!values[i]) continue;
    ++shown;
    if (best != kNone && texts[i] == texts[best]) ++same_as_best;
  }
  const std::string best_text =
      best != kNone && shown >= 2 && same_as_best < shown ? texts[best] : "";
  std::vector<std::string> out;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!values[i]) {
      out.push_back("–");
      continue;
    }
    const bool is_best = !best_text.empty() && texts[i] == best_text;
    out.push_back((is_best ? "**" + texts[i] + "**" : texts[i]) + marks[i]);
  }
  return out;
}

std::string rate_text(std::size_t successes, std::size_t runs) {
  if (runs == 0) return "–";
  return std::to_string(successes) + "/" + std::to_string(runs) + " (" +
         fixed(100.0 * static_cast<double>(successes) / runs, 0) + "%)";
}

// The preset's table header (configs/presets/NAME.yaml: header), else its name.
std::string strategy_header(const std::string& s) {
  return is_preset_name(s) ? find_preset(s).header : s;
}

std::string optional_number(const std::optional<double>& v) { return v ? shortest(*v) : ""; }

}  // namespace

const std::vector<std::string>& results_csv_columns() { return kColumns; }

void write_results_csv(std::ostream& out, const std::vector<Case>& cases,
                       const std::vector<RunRecord>& records) {
  for (std::size_t i = 0; i < kColumns.size(); ++i) out << (i ? "," : "") << kColumns[i];
  out << "\n";
  for (const RunRecord& r : records) {
    if (r.case_index >= cases.size())
      throw InvalidArgument("write_results_csv: record of an unknown case");
    const Case& c = cases[r.case_index];
    const Pose6& p = c.displacement;
    out << c.experiment << ',' << c.index << ',' << c.label << ',' << c.group << ',' << c.variable
        << ',' << shortest(c.value) << ',' << shortest(p.x_m) << ',' << shortest(p.y_m) << ','
        << shortest(p.z_m) << ',' << shortest(p.roll_deg) << ',' << shortest(p.pitch_deg) << ','
        << shortest(p.yaw_deg) << ',' << r.strategy << ',' << r.k << ','
        << shortest(r.initial_score_m2) << ',' << shortest(r.final_score_m2) << ',' << r.iterations
        << ',' << to_string(r.termination) << ',' << fixed(r.time_s, 6) << ','
        << (r.error ? shortest(r.error->rotation_deg) : "") << ','
        << (r.error ? shortest(r.error->translation_m) : "") << ','
        << (r.decision.success ? "true" : "false") << ',' << to_string(r.decision.decided_by) << ','
        << (r.trustworthy ? "true" : "false") << ',' << optional_number(r.nees) << ','
        << optional_number(r.covariance_translation_sd_m) << ','
        << optional_number(r.covariance_rotation_sd_deg) << '\n';
  }
}

namespace {

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string::npos ? comma : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return fields;
}

double parse_number(const std::string& text, const std::string& column, const std::string& file,
                    std::size_t line) {
  if (text == "inf") return std::numeric_limits<double>::infinity();
  if (text == "-inf") return -std::numeric_limits<double>::infinity();
  if (text == "nan") return std::numeric_limits<double>::quiet_NaN();
  double v = 0.0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || r.ec != std::errc() || r.ptr != text.data() + text.size())
    throw ParseError(file, line, column + ": expected a number, got '" + text + "'");
  return v;
}

long parse_integer(const std::string& text, const std::string& column, const std::string& file,
                   std::size_t line) {
  long v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || r.ec != std::errc() || r.ptr != text.data() + text.size())
    throw ParseError(file, line, column + ": expected an integer, got '" + text + "'");
  return v;
}

}  // namespace

std::vector<RunRecord> read_results_csv(std::istream& in, const std::string& file,
                                        const std::vector<Case>& cases) {
  std::string header;
  if (!std::getline(in, header))
    throw ParseError(file, 0, "empty; expected the results.csv header");
  std::string expected;
  for (std::size_t i = 0; i < kColumns.size(); ++i) expected += (i ? "," : "") + kColumns[i];
  if (header != expected) throw ParseError(file, 1, "not the results.csv header of this version");

  std::vector<RunRecord> records;
  std::string text;
  std::size_t line = 1;
  // The case being read and how many of its strategies were seen.
  std::size_t current = cases.size();
  std::size_t seen = 0;
  auto close_case = [&](std::size_t at_line) {
    if (current < cases.size() && seen != cases[current].strategies.size())
      throw ParseError(file, at_line,
                       "case " + std::to_string(current) + " has " + std::to_string(seen) + " of " +
                           std::to_string(cases[current].strategies.size()) + " strategies");
  };
  while (std::getline(in, text)) {
    ++line;
    if (in.eof()) throw ParseError(file, line, "the last line has no newline (half-written)");
    const std::vector<std::string> f = split_csv_line(text);
    if (f.size() != kColumns.size())
      throw ParseError(file, line,
                       "expected " + std::to_string(kColumns.size()) + " columns, got " +
                           std::to_string(f.size()));
    const long ci = parse_integer(f[1], "case", file, line);
    if (ci < 0 || static_cast<std::size_t>(ci) >= cases.size())
      throw ParseError(file, line, "case " + f[1] + " is not a case of this config");
    const Case& c = cases[static_cast<std::size_t>(ci)];
    const Pose6& p = c.displacement;
    const std::vector<std::string> case_cells{c.experiment,
                                              std::to_string(c.index),
                                              c.label,
                                              c.group,
                                              c.variable,
                                              shortest(c.value),
                                              shortest(p.x_m),
                                              shortest(p.y_m),
                                              shortest(p.z_m),
                                              shortest(p.roll_deg),
                                              shortest(p.pitch_deg),
                                              shortest(p.yaw_deg)};
    for (std::size_t i = 0; i < case_cells.size(); ++i) {
      if (f[i] != case_cells[i])
        throw ParseError(file, line,
                         kColumns[i] + " '" + f[i] + "' differs from case " + c.id() + " ('" +
                             case_cells[i] + "') of this config");
    }
    if (c.index != current) {
      close_case(line);
      if (current < cases.size() && c.index < current)
        throw ParseError(file, line, "case " + f[1] + " out of order");
      current = c.index;
      seen = 0;
    }
    if (seen >= c.strategies.size() || c.strategies[seen] != f[12])
      throw ParseError(file, line,
                       "strategy '" + f[12] + "' is not the next strategy of case " + c.id());
    RunRecord r;
    r.case_index = c.index;
    r.strategy = c.strategies[seen];
    r.k = static_cast<int>(parse_integer(f[13], "k", file, line));
    if (r.k != c.k) throw ParseError(file, line, "k " + f[13] + " differs from case " + c.id());
    r.initial_score_m2 = parse_number(f[14], "initial_score_m2", file, line);
    r.final_score_m2 = parse_number(f[15], "final_score_m2", file, line);
    r.iterations = static_cast<int>(parse_integer(f[16], "iterations", file, line));
    bool known = false;
    for (TerminationReason t :
         {TerminationReason::kNotTerminated, TerminationReason::kMaxIterations,
          TerminationReason::kTransform, TerminationReason::kAbsoluteMse,
          TerminationReason::kRelativeMse, TerminationReason::kNoCorrespondences,
          TerminationReason::kDegenerate}) {
      if (to_string(t) == f[17]) {
        r.termination = t;
        known = true;
      }
    }
    if (!known) throw ParseError(file, line, "unknown termination '" + f[17] + "'");
    r.time_s = parse_number(f[18], "time_s", file, line);
    if (f[19].empty() != f[20].empty())
      throw ParseError(file, line, "rotation and translation errors must both be given or empty");
    if (!f[19].empty()) {
      r.error = TransformError{parse_number(f[19], "rotation_error_deg", file, line),
                               parse_number(f[20], "translation_error_m", file, line)};
    }
    if (f[21] != "true" && f[21] != "false")
      throw ParseError(file, line, "success: expected true or false, got '" + f[21] + "'");
    r.decision.success = f[21] == "true";
    if (f[22] == to_string(SuccessCriterion::kGroundTruth)) {
      r.decision.decided_by = SuccessCriterion::kGroundTruth;
    } else if (f[22] == to_string(SuccessCriterion::kScore)) {
      r.decision.decided_by = SuccessCriterion::kScore;
    } else {
      throw ParseError(file, line, "unknown decided_by '" + f[22] + "'");
    }
    if (f[23] != "true" && f[23] != "false")
      throw ParseError(file, line, "trustworthy: expected true or false, got '" + f[23] + "'");
    r.trustworthy = f[23] == "true";
    if (!f[24].empty()) r.nees = parse_number(f[24], "nees", file, line);
    if (f[25].empty() != f[26].empty())
      throw ParseError(file, line, "covariance standard deviations must both be given or empty");
    if (!f[25].empty()) {
      r.covariance_translation_sd_m =
          parse_number(f[25], "covariance_translation_sd_m", file, line);
      r.covariance_rotation_sd_deg = parse_number(f[26], "covariance_rotation_sd_deg", file, line);
    }
    ++seen;
    records.push_back(std::move(r));
  }
  close_case(line);
  return records;
}

double median(std::vector<double> values) {
  values.erase(std::remove_if(values.begin(), values.end(), [](double v) { return std::isnan(v); }),
               values.end());
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

ReportSummary summarize(const ExperimentConfig& config, const std::vector<Case>& cases,
                        const RunnerOutcome& outcome) {
  ReportSummary s;
  s.has_ground_truth = config.has_ground_truth();
  s.interrupted = outcome.cancelled;
  s.cases_planned = outcome.cases_planned;
  s.cases_finished = outcome.cases_finished;
  s.cases_skipped = outcome.cases_skipped;
  s.runs = outcome.records.size();
  std::vector<const RunRecord*> all;
  for (const RunRecord& r : outcome.records) all.push_back(&r);
  s.overall = summarize_by_strategy(config.strategies, all);

  for (std::size_t ei = 0; ei < config.experiments.size(); ++ei) {
    const ExperimentSpec& spec = config.experiments[ei];
    ExperimentSummary e;
    e.name = spec.name;
    e.type = spec.type;
    std::vector<const RunRecord*> mine;
    std::vector<std::size_t> case_seen;
    for (const RunRecord& r : outcome.records) {
      if (cases.at(r.case_index).experiment_index != ei) continue;
      mine.push_back(&r);
      if (case_seen.empty() || case_seen.back() != r.case_index) case_seen.push_back(r.case_index);
    }
    e.cases = case_seen.size();
    e.strategies = summarize_by_strategy(spec.strategies, mine);
    if (spec.type == ExperimentType::kBasin) {
      auto add_axis = [&](const std::string& axis, const std::vector<double>& levels) {
        for (double level : levels) {
          std::vector<const RunRecord*> at;
          for (const RunRecord* r : mine) {
            const Case& c = cases[r->case_index];
            if (c.group == axis && c.value == level) at.push_back(r);
          }
          BasinLevelSummary b;
          b.axis = axis;
          b.level = level;
          b.strategies = summarize_by_strategy(spec.strategies, at);
          e.basin_levels.push_back(std::move(b));
        }
      };
      add_axis("yaw", spec.basin.yaw_levels_deg);
      add_axis("translation", spec.basin.translation_levels_m);
    }
    s.experiments.push_back(std::move(e));
  }
  return s;
}

void write_summary_json(std::ostream& out, const ExperimentConfig& config,
                        const ReportSummary& summary) {
  nlohmann::ordered_json j;
  j["config"] = config.path;
  j["source"] = config.source.path;
  j["target"] = config.target.path;
  j["ground_truth"] = config.ground_truth.kind == GroundTruthSpec::Kind::kNone ? "none"
                      : config.ground_truth.kind == GroundTruthSpec::Kind::kIdentity
                          ? "identity"
                          : config.ground_truth.path;
  j["success_criterion"] = summary.has_ground_truth ? "ground_truth" : "score";
  if (summary.has_ground_truth) {
    j["success_rotation_deg"] = config.success.rotation_deg;
    j["success_translation_m"] = config.success.translation_m;
  } else {
    j["success_score_m2"] = config.success.score_m2;
  }
  // The limits given to every strategy (null: each keeps its own).
  j["max_iterations"] =
      config.max_iterations ? nlohmann::json(*config.max_iterations) : nlohmann::json();
  j["max_distance_m"] = config.max_distance_m ? num(*config.max_distance_m) : nlohmann::json();
  j["covariance_norm"] = to_string(config.covariance_norm);
  j["interrupted"] = summary.interrupted;
  j["cases_planned"] = summary.cases_planned;
  j["cases_finished"] = summary.cases_finished;
  j["cases_skipped_by_escalation"] = summary.cases_skipped;
  j["runs"] = summary.runs;
  auto per_strategy = [](const std::vector<StrategySummary>& v, bool with_time) {
    nlohmann::ordered_json o = nlohmann::ordered_json::object();
    for (const StrategySummary& s : v) o[s.strategy] = strategy_json(s, with_time);
    return o;
  };
  j["per_strategy"] = per_strategy(summary.overall, true);
  nlohmann::ordered_json ex = nlohmann::ordered_json::object();
  for (const ExperimentSummary& e : summary.experiments) {
    nlohmann::ordered_json o;
    o["type"] = to_string(e.type);
    o["cases"] = e.cases;
    o["per_strategy"] = per_strategy(e.strategies, true);
    if (e.type == ExperimentType::kBasin) {
      nlohmann::ordered_json levels = nlohmann::ordered_json::array();
      for (const BasinLevelSummary& b : e.basin_levels) {
        nlohmann::ordered_json l;
        l["axis"] = b.axis;
        l["level"] = b.level;
        l["unit"] = b.axis == "yaw" ? "deg" : "m";
        l["per_strategy"] = per_strategy(b.strategies, false);
        levels.push_back(l);
      }
      o["levels"] = levels;
    }
    ex[e.name] = o;
  }
  j["per_experiment"] = ex;
  out << j.dump(2) << "\n";
}

namespace {

// The report's head: the config, the maps, the limits, what success means, what ran.
void write_report_intro(std::ostream& out, const ExperimentConfig& config,
                        const ReportSummary& summary) {
  const bool gt = summary.has_ground_truth;
  out << "# Experiment report: " << config.name << "\n\n";
  out << "- config: `" << config.path << "`\n";
  out << "- source: `" << config.source.path << "`"
      << (config.source.split ? " frames " + std::to_string(config.source.first_frame_id) + "-" +
                                    std::to_string(config.source.last_frame_id)
                              : std::string())
      << "; target: `" << config.target.path << "`"
      << (config.target.split ? " frames " + std::to_string(config.target.first_frame_id) + "-" +
                                    std::to_string(config.target.last_frame_id)
                              : std::string())
      << "\n";
  out << "- limits: max iterations "
      << (config.max_iterations ? std::to_string(*config.max_iterations)
                                : std::string("each strategy's own"))
      << ", max correspondence distance "
      << (!config.max_distance_m               ? std::string("each strategy's own")
          : std::isinf(*config.max_distance_m) ? std::string("infinite")
                                               : shortest(*config.max_distance_m) + " m")
      << "\n";
  if (gt) {
    out << "- success = right basin: rotation error < " << shortest(config.success.rotation_deg)
        << "° and translation error < " << shortest(config.success.translation_m)
        << " m against the ground truth; accuracy = medians over the successful runs\n";
  } else {
    out << "- no ground truth: success = final score < " << shortest(config.success.score_m2)
        << " m² (the paper's criterion)\n";
  }
  out << "- " << summary.cases_finished << " of " << summary.cases_planned << " cases, "
      << summary.runs << " runs";
  if (summary.cases_skipped > 0)
    out << "; " << summary.cases_skipped << " escalation levels not needed";
  if (summary.interrupted) out << "; **interrupted: partial results**";
  out << "\n\n";
}

// The overview tables: success rate (and accuracy with a ground truth) per experiment and
// strategy.
void write_overview(std::ostream& out, const ReportSummary& summary) {
  const bool gt = summary.has_ground_truth;
  std::vector<std::string> all_strategies;
  for (const StrategySummary& s : summary.overall) all_strategies.push_back(s.strategy);
  std::vector<std::string> header{"experiment"};
  for (const std::string& s : all_strategies) header.push_back(strategy_header(s));
  out << "## Overview\n\n### Success rate\n\n" << md_row(header) << md_rule(header.size());
  auto overview_rows = [&](auto cell_value, auto cell_text, bool higher) {
    auto row_for = [&](const std::string& name, const std::vector<StrategySummary>& v) {
      std::vector<std::optional<double>> values;
      std::vector<std::string> texts, marks;
      for (const std::string& s : all_strategies) {
        const auto it = std::find_if(v.begin(), v.end(),
                                     [&](const StrategySummary& x) { return x.strategy == s; });
        if (it == v.end()) {
          values.push_back(std::nullopt);
          texts.emplace_back();
        } else {
          values.push_back(cell_value(*it));
          texts.push_back(cell_text(*it));
        }
        marks.emplace_back();
      }
      std::vector<std::string> cells{name};
      for (const std::string& c : bold_best(values, texts, marks, higher)) cells.push_back(c);
      out << md_row(cells);
    };
    for (const ExperimentSummary& e : summary.experiments) row_for(e.name, e.strategies);
    row_for("**all**", summary.overall);
  };
  overview_rows([](const StrategySummary& s) { return s.success_rate; },
                [](const StrategySummary& s) { return rate_text(s.successes, s.runs); }, true);
  if (gt) {
    out << "\n### Accuracy: median rotation error of the successful runs (°)\n\n"
        << md_row(header) << md_rule(header.size());
    overview_rows([](const StrategySummary& s) { return s.median_rotation_error_deg; },
                  [](const StrategySummary& s) {
                    return std::isnan(s.median_rotation_error_deg)
                               ? std::string("–")
                               : fixed(s.median_rotation_error_deg, 2);
                  },
                  false);
    out << "\n### Accuracy: median translation error of the successful runs (cm)\n\n"
        << md_row(header) << md_rule(header.size());
    overview_rows([](const StrategySummary& s) { return s.median_translation_error_m; },
                  [](const StrategySummary& s) {
                    return std::isnan(s.median_translation_error_m)
                               ? std::string("–")
                               : fixed(100.0 * s.median_translation_error_m, 1);
                  },
                  false);
  }
  out << "\n";
}

// A basin experiment's table: success rate per level.
void write_basin_table(std::ostream& out, const ExperimentSpec& spec, const ExperimentSummary& es,
                       const std::vector<std::string>& h) {
  out << "Success rate per level (" << spec.basin.samples << " seeded draws per level, seed "
      << spec.basin.seed << "; yaw pivot: " << to_string(spec.basin.yaw_pivot)
      << "); highest of each row in bold.\n\n"
      << md_row(h) << md_rule(h.size());
  for (const BasinLevelSummary& b : es.basin_levels) {
    std::vector<std::optional<double>> values;
    std::vector<std::string> texts, marks;
    bool any = false;
    for (const std::string& s : spec.strategies) {
      const auto it = std::find_if(b.strategies.begin(), b.strategies.end(),
                                   [&](const StrategySummary& x) { return x.strategy == s; });
      if (it == b.strategies.end()) {
        values.push_back(std::nullopt);
        texts.emplace_back();
      } else {
        any = true;
        values.push_back(it->success_rate);
        texts.push_back(rate_text(it->successes, it->runs));
      }
      marks.emplace_back();
    }
    if (!any) continue;
    std::vector<std::string> cells{b.axis == "yaw" ? "yaw " + shortest(b.level) + "°"
                                                   : "translation " + shortest(b.level) + " m"};
    for (const std::string& c : bold_best(values, texts, marks, true)) cells.push_back(c);
    out << md_row(cells);
  }
  out << "\n";
}

// The other experiments' tables: one row per finished case, per metric.
void write_case_tables(std::ostream& out, const std::vector<Case>& cases,
                       const RunnerOutcome& outcome, bool gt, std::size_t ei,
                       const ExperimentSpec& spec, const std::vector<std::string>& h) {
  // One row per finished case.
  std::map<std::size_t, std::vector<const RunRecord*>> by_case;
  for (const RunRecord& r : outcome.records) {
    if (cases.at(r.case_index).experiment_index == ei) by_case[r.case_index].push_back(&r);
  }
  struct Metric {
    std::string title;
    std::function<double(const RunRecord&)> value;
    std::function<std::string(double)> text;
  };
  std::vector<Metric> metrics{{"Final score (×10⁻³ m²)",
                               [](const RunRecord& r) { return r.final_score_m2; },
                               [](double v) { return fixed(v * 1e3, 4); }}};
  if (gt) {
    metrics.push_back({"Rotation error (°)",
                       [](const RunRecord& r) { return r.error ? r.error->rotation_deg : NAN; },
                       [](double v) { return fixed(v, 2); }});
    metrics.push_back({"Translation error (cm)",
                       [](const RunRecord& r) { return r.error ? r.error->translation_m : NAN; },
                       [](double v) { return fixed(v * 100.0, 1); }});
  }
  for (const Metric& m : metrics) {
    out << m.title << ": lowest of each row in bold; ✗ = failed ("
        << (gt ? "wrong basin" : "score above the threshold") << ").\n\n"
        << md_row(h) << md_rule(h.size());
    for (const auto& [ci, runs] : by_case) {
      std::vector<std::optional<double>> values;
      std::vector<std::string> texts, marks;
      for (const std::string& s : spec.strategies) {
        const auto it = std::find_if(runs.begin(), runs.end(),
                                     [&](const RunRecord* r) { return r->strategy == s; });
        if (it == runs.end()) {
          values.push_back(std::nullopt);
          texts.emplace_back();
          marks.emplace_back();
        } else {
          const double v = m.value(**it);
          values.push_back(v);
          texts.push_back(m.text(v));
          marks.push_back((*it)->decision.success ? "" : " ✗");
        }
      }
      std::vector<std::string> cells{cases[ci].label};
      for (const std::string& c : bold_best(values, texts, marks, false)) cells.push_back(c);
      out << md_row(cells);
    }
    out << "\n";
  }
}

}  // namespace

void write_tables_markdown(std::ostream& out, const ExperimentConfig& config,
                           const std::vector<Case>& cases, const RunnerOutcome& outcome,
                           const ReportSummary& summary) {
  write_report_intro(out, config, summary);
  write_overview(out, summary);
  for (std::size_t ei = 0; ei < config.experiments.size(); ++ei) {
    const ExperimentSpec& spec = config.experiments[ei];
    const ExperimentSummary& es = summary.experiments[ei];
    out << "## " << spec.name << " (" << to_string(spec.type) << ")\n\n";
    std::vector<std::string> h{spec.type == ExperimentType::kBasin ? "level" : "case"};
    for (const std::string& s : spec.strategies) h.push_back(strategy_header(s));
    if (es.cases == 0) {
      out << "No finished case.\n\n";
      continue;
    }
    if (spec.type == ExperimentType::kBasin) {
      write_basin_table(out, spec, es, h);
    } else {
      write_case_tables(out, cases, outcome, summary.has_ground_truth, ei, spec, h);
    }
  }
}

void write_history_csv(std::ostream& out, const Case& c, const std::vector<RunRecord>& records) {
  out << "case,experiment,label,strategy,iteration,num_correspondences,mse_m2,score_m2\n";
  for (const RunRecord& r : records) {
    for (const IterationRecord& it : r.history) {
      out << c.index << ',' << c.experiment << ',' << c.label << ',' << r.strategy << ','
          << it.iteration << ',' << it.num_correspondences << ',' << shortest(it.mse_m2) << ','
          << (std::isnan(it.score_m2) ? std::string() : shortest(it.score_m2)) << '\n';
    }
  }
}

void write_alignment_points_csv(std::ostream& out, const Case& c, const Points3& source_points,
                                const Points3& target_points,
                                const std::vector<RunRecord>& records) {
  out << "case,experiment,label,cloud,x,y,z\n";
  auto write = [&](const std::string& cloud, const Isometry3& T, const Points3& pts) {
    for (const Vec3& p0 : pts) {
      const Vec3 p = T * p0;
      out << c.index << ',' << c.experiment << ',' << c.label << ',' << cloud << ','
          << fixed(p.x(), 5) << ',' << fixed(p.y(), 5) << ',' << fixed(p.z(), 5) << '\n';
    }
  };
  write("target", Isometry3::Identity(), target_points);
  write("initial", c.D, source_points);
  for (const RunRecord& r : records) write(r.strategy, r.T_target_source * c.D, source_points);
}

}  // namespace lmalign
