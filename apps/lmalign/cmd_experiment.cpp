// `lmalign experiment`: run an experiment protocol written in YAML (the paper's Tables 1-4,
// convergence basins) and write a report folder: results.csv, summary.json, tables.md, plots.
// See docs/experiments.md.
#include <omp.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/experiment/report.hpp"
#include "lmalign/experiment/runner.hpp"
#include "lmalign/io/output_file.hpp"

namespace lmalign::cli {

namespace {

namespace fs = std::filesystem;

struct ExperimentArgs {
  std::string config;
  std::string output;
  int threads = 0;
  bool no_plots = false;
  std::string plot_case;
  std::vector<std::string> only;
  std::string resume;
};

/// A resolved config.yaml without its leading comment lines (they name the file it came from):
/// two runs used the same config exactly when these agree.
std::string config_body(const std::string& resolved) {
  std::size_t pos = 0;
  while (pos < resolved.size() && resolved[pos] == '#') {
    const std::size_t nl = resolved.find('\n', pos);
    if (nl == std::string::npos) return {};
    pos = nl + 1;
  }
  return resolved.substr(pos);
}

/// The config file a resolved config.yaml was resolved from (its first comment line), or empty.
std::string resolved_from(const std::string& resolved) {
  const std::string head = "# Resolved by lmalign experiment from ";
  const std::string tail = ": every default filled in";
  if (resolved.compare(0, head.size(), head) != 0) return {};
  const std::size_t end = resolved.find(tail, head.size());
  const std::size_t nl = resolved.find('\n');
  if (end == std::string::npos || (nl != std::string::npos && end > nl)) return {};
  return resolved.substr(head.size(), end - head.size());
}

std::string read_whole_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot read '" + path + "'");
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

/// $LMALIGN_DATA, else ../shared/data beside the source checkout (as the Makefile), else empty.
std::string data_dir() {
  if (const char* env = std::getenv("LMALIGN_DATA"); env != nullptr && *env != '\0') return env;
  const fs::path root = source_checkout();
  std::error_code ec;
  if (!root.empty() && fs::is_directory(root.parent_path() / "shared" / "data", ec)) {
    return (root.parent_path() / "shared" / "data").lexically_normal().string();
  }
  return {};
}

std::string duration_text(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const long s = static_cast<long>(seconds + 0.5);
  char buf[32];
  if (s >= 3600) {
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  }
  return buf;
}

/// A one-line progress bar with ETA on stderr, drawn only when stderr is a terminal.
class ProgressBar {
 public:
  ProgressBar() : enabled_(::isatty(STDERR_FILENO) == 1), start_(Clock::now()) {}
  void update(const RunnerProgress& p) {
    if (!enabled_) return;
    const auto now = Clock::now();
    const bool last = p.runs_done >= p.runs_total;
    if (!last && drawn_ && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    drawn_ = true;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const double frac = p.runs_total > 0 ? static_cast<double>(p.runs_done) / p.runs_total : 1.0;
    const int width = 30;
    const int filled = static_cast<int>(frac * width);
    std::string bar(static_cast<std::size_t>(filled), '=');
    if (filled < width) bar += '>' + std::string(static_cast<std::size_t>(width - filled - 1), ' ');
    const double eta = p.runs_done > 0 ? elapsed * (p.runs_total - p.runs_done) / p.runs_done : NAN;
    std::fprintf(stderr, "\r[%s] %zu/%zu runs %3.0f%%  %s elapsed  ETA %s \033[K", bar.c_str(),
                 p.runs_done, p.runs_total, 100.0 * frac, duration_text(elapsed).c_str(),
                 duration_text(eta).c_str());
    std::fflush(stderr);
  }
  void finish() {
    if (enabled_ && drawn_) {
      std::fprintf(stderr, "\n");
      std::fflush(stderr);
    }
    drawn_ = false;
  }

 private:
  using Clock = std::chrono::steady_clock;
  bool enabled_;
  bool drawn_ = false;
  Clock::time_point start_;
  Clock::time_point last_draw_{};
};

std::string rate_cell(const StrategySummary& s) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%zu/%zu", s.successes, s.runs);
  return buf;
}

void print_summary(const ReportSummary& summary) {
  std::vector<std::string> strategies;
  for (const StrategySummary& s : summary.overall) strategies.push_back(s.strategy);
  std::size_t name_width = 10;
  for (const ExperimentSummary& e : summary.experiments)
    name_width = std::max(name_width, e.name.size());
  say("\nsuccess (%s) per strategy:\n", summary.has_ground_truth
                                            ? "right basin against the ground truth"
                                            : "score below the threshold");
  say("  %-*s", static_cast<int>(name_width), "experiment");
  for (const std::string& s : strategies) say(" %13s", s.c_str());
  say("\n");
  auto row = [&](const std::string& name, const std::vector<StrategySummary>& v, auto cell) {
    say("  %-*s", static_cast<int>(name_width), name.c_str());
    for (const std::string& s : strategies) {
      std::string text = "-";
      for (const StrategySummary& x : v) {
        if (x.strategy == s) text = cell(x);
      }
      say(" %13s", text.c_str());
    }
    say("\n");
  };
  for (const ExperimentSummary& e : summary.experiments) row(e.name, e.strategies, rate_cell);
  row("all", summary.overall, rate_cell);
  if (summary.has_ground_truth) {
    say("accuracy (median over successful runs), rotation deg / translation cm:\n");
    row("all", summary.overall, [](const StrategySummary& s) {
      if (std::isnan(s.median_rotation_error_deg)) return std::string("-");
      char buf[48];
      std::snprintf(buf, sizeof buf, "%.2f / %.1f", s.median_rotation_error_deg,
                    100.0 * s.median_translation_error_m);
      return std::string(buf);
    });
  }
}

// Where an experiment reads and writes: its config (resolved), the output folder, and for
// --resume the config the interrupted run stored.
struct ExperimentPlan {
  ExperimentConfig config;
  bool resuming = false;
  std::string stored_config;  // --resume: the resolved config.yaml of the interrupted run
  std::string out_dir;
  fs::path out;
  std::string csv_path;
};

// The config to run and the folder to write, checked before anything is read or written.
ExperimentPlan plan_experiment(ExperimentArgs& a) {
  ExperimentPlan p;
  p.resuming = !a.resume.empty();
  if (!a.output.empty()) refuse_standard_output_folder("--output", a.output);
  if (p.resuming) refuse_standard_output_folder("--resume", a.resume);
  if (p.resuming) {
    if (!a.output.empty() &&
        fs::path(a.output).lexically_normal() != fs::path(a.resume).lexically_normal()) {
      throw InvalidArgument("--resume '" + a.resume + "' and --output '" + a.output +
                            "' name different folders (--resume writes into its own folder)");
    }
    std::error_code ec;
    for (const char* name : {"config.yaml", "results.csv"}) {
      if (!fs::is_regular_file(fs::path(a.resume) / name, ec)) {
        throw InvalidArgument("--resume '" + a.resume + "' holds no run to resume (no " + name +
                              ")");
      }
    }
    p.stored_config = read_whole_file((fs::path(a.resume) / "config.yaml").string());
  } else if (a.config.empty()) {
    throw InvalidArgument("experiment: CONFIG is required (or --resume OUTDIR)");
  }
  ConfigLoadOptions lo;
  lo.data_dir = data_dir();
  if (!a.config.empty()) {
    p.config = load_experiment_config(a.config, lo);
  } else {
    // --resume alone: the run's own config.yaml, reported under the name it was resolved from
    // (so that summary.json and tables.md read as those of an uninterrupted run).
    a.config = (fs::path(a.resume) / "config.yaml").string();
    p.config = load_experiment_config(a.config, lo);
    if (const std::string from = resolved_from(p.stored_config); !from.empty()) {
      p.config.path = from;
      p.config.name = fs::path(from).stem().string();
    }
  }
  if (!a.only.empty()) select_experiments(p.config, a.only);
  p.out_dir = p.resuming         ? a.resume
              : a.output.empty() ? (fs::path("out") / p.config.name).string()
                                 : a.output;
  p.out = fs::path(p.out_dir);
  p.csv_path = (p.out / "results.csv").string();
  std::vector<std::string> inputs{p.config.source.path, p.config.target.path,
                                  p.config.ground_truth.path};
  if (!p.resuming) inputs.push_back(a.config);  // --resume reads and rewrites its config.yaml
  for (const char* name : {"config.yaml", "results.csv", "summary.json", "tables.md", "history.csv",
                           "alignment_points.csv"}) {
    refuse_output_over_input(p.resuming ? "--resume" : "--output", (p.out / name).string(), inputs);
  }
  std::error_code ec;
  if (fs::exists(p.out, ec) && !fs::is_directory(p.out, ec)) {
    throw InvalidArgument("--output '" + p.out_dir + "' exists and is not a folder");
  }
  return p;
}

// --resume: the same config exactly, and the finished cases of results.csv.
std::vector<RunRecord> finished_records(const ExperimentPlan& p, const std::string& resolved,
                                        const std::vector<Case>& cases) {
  if (!p.resuming) return {};
  if (config_body(resolved) != config_body(p.stored_config)) {
    throw InvalidArgument("--resume '" + p.out_dir +
                          "': the config differs from the one of the "
                          "interrupted run (" +
                          (p.out / "config.yaml").string() +
                          "); resume with that config, or start a new run");
  }
  std::ifstream in(p.csv_path, std::ios::binary);
  if (!in) throw IoError("cannot read '" + p.csv_path + "'");
  return read_results_csv(in, p.csv_path, cases);
}

void print_plan(const ExperimentArgs& a, const ExperimentPlan& p, const ExperimentInputs& in,
                const std::vector<Case>& cases, const std::vector<RunRecord>& already_finished,
                int threads) {
  const ExperimentConfig& config = p.config;
  std::size_t cases_already_finished = 0;
  for (std::size_t i = 0; i < already_finished.size(); ++i) {
    if (i == 0 || already_finished[i].case_index != already_finished[i - 1].case_index)
      ++cases_already_finished;
  }
  std::size_t runs = 0;
  for (const Case& c : cases) runs += c.strategies.size();
  say("lmalign experiment: %s -> %s\n", a.config.c_str(), p.out_dir.c_str());
  say("  source %s (%zu landmarks), target %s (%zu landmarks)\n", config.source.path.c_str(),
      in.source.landmarks.size(), config.target.path.c_str(), in.target.landmarks.size());
  if (in.source_left_out + in.target_left_out > 0) {
    say("  %s\n", left_out_message(in.source_left_out, in.target_left_out).c_str());
  }
  if (config.has_ground_truth()) {
    say("  ground truth: %s; success = rotation error < %g deg and translation error < %g m\n",
        config.ground_truth.kind == GroundTruthSpec::Kind::kIdentity
            ? "identity"
            : config.ground_truth.path.c_str(),
        config.success.rotation_deg, config.success.translation_m);
  } else {
    say("  no ground truth; success = final score < %g m^2\n", config.success.score_m2);
  }
  say("  %zu experiments, %zu cases, %zu runs (case x strategy), %d threads\n",
      config.experiments.size(), cases.size(), runs, threads);
  if (p.resuming) {
    say("  resuming: %zu cases (%zu runs) already finished in %s are not run again\n",
        cases_already_finished, already_finished.size(), p.csv_path.c_str());
  }
  std::fflush(stdout);
}

// The folder starts with the resolved config and a valid results.csv (header-only, or the
// finished cases when resuming); stale outputs of an earlier run are removed so that nothing in
// it disagrees with this run. When resuming, the plot case's files stay if it is finished.
void start_output_folder(const ExperimentPlan& p, const std::string& resolved,
                         const std::vector<Case>& cases,
                         const std::vector<RunRecord>& already_finished,
                         std::optional<std::size_t> plot_case) {
  const bool plot_case_finished =
      plot_case && std::any_of(already_finished.begin(), already_finished.end(),
                               [&](const RunRecord& r) { return r.case_index == *plot_case; });
  std::error_code ec;
  create_output_folder(p.out_dir);
  for (const char* name : {"summary.json", "tables.md"}) fs::remove(p.out / name, ec);
  if (!plot_case_finished) {
    for (const char* name : {"history.csv", "alignment_points.csv"}) fs::remove(p.out / name, ec);
  }
  if (fs::is_directory(p.out / "plots", ec)) {
    for (const auto& entry : fs::directory_iterator(p.out / "plots", ec)) {
      if (entry.path().extension() == ".png") fs::remove(entry.path(), ec);
    }
  }
  if (!p.resuming) {
    write_output((p.out / "config.yaml").string(), [&](std::ostream& o) { o << resolved; });
  }
  write_output(p.csv_path, [&](std::ostream& o) { write_results_csv(o, cases, already_finished); });
}

// The cases on the runner, with a progress bar; finished cases flushed to results.csv (whole
// file, atomically) as each one completes, the plot case's history and alignment as soon as it
// completes (so that a resumed run has them). `finished` gets every finished case's records.
RunnerOutcome run_with_progress(const ExperimentPlan& p, const ExperimentInputs& in,
                                const std::vector<Case>& cases, const PreparedTarget& target,
                                const std::vector<RunRecord>& already_finished,
                                std::optional<std::size_t> plot_case, int threads,
                                std::map<std::size_t, std::vector<RunRecord>>* finished) {
  const Points3 source_points = in.source.positions();
  for (const RunRecord& r : already_finished) (*finished)[r.case_index].push_back(r);
  ProgressBar bar;
  RunnerOptions ro;
  ro.threads = threads;
  ro.history_case = plot_case;
  ro.cancel = &stop_flag();
  ro.on_progress = [&](const RunnerProgress& pr) { bar.update(pr); };
  ro.on_case_finished = [&](const Case& c, const std::vector<RunRecord>& records) {
    (*finished)[c.index] = records;
    write_output(p.csv_path, [&](std::ostream& o) {
      std::vector<RunRecord> rows;
      for (const auto& [index, recs] : *finished) rows.insert(rows.end(), recs.begin(), recs.end());
      write_results_csv(o, cases, rows);
    });
    if (plot_case && c.index == *plot_case) {
      write_output((p.out / "history.csv").string(),
                   [&](std::ostream& o) { write_history_csv(o, c, records); });
      write_output((p.out / "alignment_points.csv").string(), [&](std::ostream& o) {
        write_alignment_points_csv(o, c, source_points, target.points(), records);
      });
    }
  };
  ro.already_finished = already_finished;
  SourceDescription source_description;
  describe_inputs(in, source_description, ro);

  stop_flag().store(false);
  RunnerOutcome outcome;
  {
    const StopSignals signals;
    outcome = run_cases(p.config, cases, source_points, target, in.ground_truth, ro);
    bar.finish();
  }
  return outcome;
}

// The plots (scripts/plot_experiment.py); a warning, never an error, when they cannot be drawn.
// Returns whether they were drawn.
bool plot_experiment(const ExperimentPlan& p, std::optional<std::size_t> plot_case) {
  std::error_code ec;
  const std::string script = find_script("plot_experiment.py", "LMALIGN_PLOT_SCRIPT");
  if (script.empty() || !fs::exists(script, ec)) {
    std::fprintf(stderr,
                 "lmalign: warning: no plots: plot_experiment.py is neither installed beside "
                 "this executable (../share/lmalign/scripts) nor in its source checkout (set "
                 "LMALIGN_PLOT_SCRIPT); the report is complete without them\n");
    return false;
  }
  std::vector<std::string> argv{p.out_dir, "--quiet"};
  if (plot_case) {
    argv.push_back("--case");
    argv.push_back(std::to_string(*plot_case));
  }
  const int rc = draw_plots(script, argv, (p.out / "plots").string());
  if (rc != 0) {
    std::fprintf(stderr,
                 "lmalign: warning: plotting failed (%s %s exited with %d; it needs matplotlib "
                 "and numpy; set LMALIGN_PYTHON to choose the interpreter). The report is "
                 "complete without plots; rerun: %s %s %s\n",
                 python_interpreter().c_str(), script.c_str(), rc, python_interpreter().c_str(),
                 script.c_str(), p.out_dir.c_str());
    return false;
  }
  say("plots: %s (drawn by %s)\n", (p.out / "plots").string().c_str(), script.c_str());
  return true;
}

int run_experiment(ExperimentArgs a) {
  const auto t0 = std::chrono::steady_clock::now();
  ExperimentPlan p = plan_experiment(a);
  ExperimentConfig& config = p.config;
  const ExperimentInputs in = load_experiment_inputs(config);
  const std::vector<Case> cases = expand_cases(config, in.source.positions());
  if (!a.plot_case.empty()) {
    config.plot_case = a.plot_case;
  } else if (!a.only.empty() && !config.plot_case.empty() && !find_case(cases, config.plot_case)) {
    config.plot_case.clear();  // the config's plot case is in an experiment left out by --only
  }
  const std::optional<std::size_t> plot_case = default_plot_case(config, cases);
  const std::string resolved = resolved_config_yaml(config);
  const std::vector<RunRecord> already_finished = finished_records(p, resolved, cases);
  const int threads = a.threads > 0 ? a.threads : std::max(1, omp_get_num_procs());
  print_plan(a, p, in, cases, already_finished, threads);
  start_output_folder(p, resolved, cases, already_finished, plot_case);

  const PreparedTarget target(in.target, WeightOptions{config.covariance_norm});
  std::map<std::size_t, std::vector<RunRecord>> finished;
  const RunnerOutcome outcome =
      run_with_progress(p, in, cases, target, already_finished, plot_case, threads, &finished);

  write_output(p.csv_path, [&](std::ostream& o) { write_results_csv(o, cases, outcome.records); });
  const ReportSummary summary = summarize(config, cases, outcome);
  write_output((p.out / "summary.json").string(),
               [&](std::ostream& o) { write_summary_json(o, config, summary); });
  write_output((p.out / "tables.md").string(),
               [&](std::ostream& o) { write_tables_markdown(o, config, cases, outcome, summary); });
  std::error_code ec;
  const bool have_plot_case = plot_case && finished.count(*plot_case) != 0 &&
                              fs::exists(p.out / "history.csv", ec) &&
                              fs::exists(p.out / "alignment_points.csv", ec);

  if (outcome.cancelled) {
    say("interrupted: %zu of %zu cases finished; results.csv holds them (%s); finish "
        "with: lmalign experiment --resume %s\n",
        outcome.cases_finished, outcome.cases_planned, p.csv_path.c_str(), p.out_dir.c_str());
    std::fflush(stdout);
    return 130;
  }

  print_summary(summary);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  say("\n%zu cases, %zu runs in %.1f s", outcome.cases_finished, outcome.records.size(), elapsed);
  if (outcome.runs_shared > 0)
    say(" (%zu identical to another run: run once)", outcome.runs_shared);
  if (outcome.cases_skipped > 0) say(" (%zu escalation levels not needed)", outcome.cases_skipped);
  say("\n");
  const bool plotted = !a.no_plots && plot_experiment(p, have_plot_case ? plot_case : std::nullopt);
  say("report: %s (results.csv, summary.json, tables.md%s)\n", p.out_dir.c_str(),
      plotted ? ", plots/" : "");
  return 0;
}

}  // namespace

CommandRunner add_experiment_command(CLI::App& root) {
  auto args = std::make_shared<ExperimentArgs>();
  CLI::App* cmd = root.add_subcommand(
      "experiment",
      "Run an experiment protocol written in YAML (docs/experiments.md): the paper's Tables 1-4\n"
      "(configs/paper.yaml), convergence basins (configs/basin.yaml), or your own. Writes\n"
      "results.csv, summary.json, tables.md and plots/ into the output folder.\n"
      "Ctrl-C (SIGINT) or SIGTERM stops after the runs in flight; results.csv then holds the\n"
      "finished cases (exit 130) and --resume OUTDIR runs the rest.");
  cmd->add_option("CONFIG", args->config,
                  "experiment config (YAML); with --resume, optional (OUTDIR/config.yaml)");
  cmd->add_option("-o,--output", args->output, "output folder (default: out/<config name>)");
  cmd->add_option("--threads", args->threads, "worker threads (default: every core)")
      ->check(CLI::Range(1, 4096));
  cmd->add_flag("--no-plots", args->no_plots, "do not call scripts/plot_experiment.py");
  cmd->add_option("--plot-case", args->plot_case,
                  "case whose score history and alignment are plotted: its index (results.csv's "
                  "case column) or <experiment>/<label>, e.g. table1_k/k=5");
  cmd->add_option("--only", args->only, "run only these experiments (by name)")->delimiter(',');
  cmd->add_option("--resume", args->resume,
                  "finish the interrupted run in OUTDIR: keep the cases in its results.csv, run "
                  "the rest (refused if CONFIG/--only/--plot-case differ from its config.yaml)")
      ->type_name("OUTDIR");
  return [args]() { return run_experiment(*args); };
}

}  // namespace lmalign::cli
