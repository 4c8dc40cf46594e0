// `lmalign experiment`: the real binary on a small synthetic protocol in a temporary folder.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lmalign/core/geometry.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/run_cli.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

const std::string kHeader =
    "experiment,case,label,group,variable,value,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg,"
    "strategy,k,initial_score_m2,final_score_m2,iterations,termination,time_s,"
    "rotation_error_deg,translation_error_m,success,decided_by,trustworthy,nees,"
    "covariance_translation_sd_m,covariance_rotation_sd_deg";

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

std::vector<std::string> fields_of(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ls(line);
  std::string cell;
  while (std::getline(ls, cell, ',')) f.push_back(cell);
  if (!line.empty() && line.back() == ',') f.emplace_back();
  return f;
}

/// results.csv parsed and checked: the documented header, then complete rows only.
std::vector<std::vector<std::string>> read_results(const std::string& path) {
  const std::string text = test::read_text(path);
  EXPECT_FALSE(text.empty()) << path;
  EXPECT_EQ(text.back(), '\n') << "a half-written last line";
  const auto lines = lines_of(text);
  EXPECT_FALSE(lines.empty());
  if (lines.empty()) return {};
  EXPECT_EQ(lines[0], kHeader);
  std::vector<std::vector<std::string>> rows;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    rows.push_back(fields_of(lines[i]));
    EXPECT_EQ(rows.back().size(), 27u) << lines[i];
  }
  return rows;
}

/// The CSV text without its time_s column (index 18).
std::string without_time(const std::string& text) {
  std::string out;
  for (const std::string& line : lines_of(text)) {
    auto f = fields_of(line);
    if (f.size() > 18) f.erase(f.begin() + 18);
    for (const std::string& x : f) out += x + ",";
    out += "\n";
  }
  return out;
}

/// scripts/plot_experiment.py of this checkout.
std::string plot_script() {
  return (fs::path(__FILE__).parent_path().parent_path().parent_path() / "scripts" /
          "plot_experiment.py")
      .string();
}

bool has_matplotlib() {
  return std::system("/usr/bin/python3 -c 'import matplotlib, numpy' >/dev/null 2>&1") == 0;
}

bool is_png(const fs::path& path) {
  const std::string bytes = test::read_text(path);
  return bytes.size() > 8 && bytes.compare(0, 8, std::string("\x89PNG\r\n\x1a\n", 8)) == 0;
}

class CliExperiment : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    const Points3 pts = test::room_points(900, 21);
    const Map target = test::map_from_points(pts, 22);
    Map source = target;
    source.landmarks.resize(600);  // partial overlap
    T_true_ = pose_from_xyz_rpy_deg(0.04, -0.02, 0.01, 1, 0, 2);
    write_map(path("target.txt"), target);
    write_map(path("source.txt"), transform_map(source, T_true_.inverse()));
    write_transform(path("gt.txt"), T_true_);
  }

  /// A config in the temporary folder (paths in it are relative to it).
  std::string config(const std::string& name, const std::string& experiments,
                     const std::string& extra = "ground_truth: gt.txt\n") {
    std::ofstream(path(name)) << "source: source.txt\ntarget: target.txt\n"
                              << extra << "strategies: [base, observations]\nexperiments:\n"
                              << experiments;
    return path(name);
  }

  std::string small_config() {
    return config("cfg.yaml",
                  "  - {name: ks, type: k, k_values: [1, 5], pose: {x_m: 0.1, yaw_deg: 5}}\n"
                  "  - {name: yaws, type: yaw, yaw_deg: [0, 20, 120]}\n"
                  "  - {name: bas, type: basin, levels: {yaw_deg: [0, 30], translation_m: [0.5]}, "
                  "samples: 2}\n");
  }

  Isometry3 T_true_;
};

TEST_F(CliExperiment, WritesTheWholeReport) {
  const test::CliRun r =
      run("experiment " + small_config() + " -o " + path("out") + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("10 cases, 20 runs"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("report: " + path("out")), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("ETA"), std::string::npos)
      << "no progress bar when stderr is not a terminal";

  // results.csv: 10 cases x 2 strategies, in case order, judged against the ground truth.
  const auto rows = read_results(path("out/results.csv"));
  ASSERT_EQ(rows.size(), 20u);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i][1], std::to_string(i / 2));
    EXPECT_EQ(rows[i][12], i % 2 == 0 ? "base" : "observations");
    EXPECT_EQ(rows[i][22], "ground_truth");
    EXPECT_FALSE(rows[i][19].empty());
  }
  EXPECT_EQ(rows[0][0], "ks");
  EXPECT_EQ(rows[0][21], "true");  // a small displacement: the right basin
  EXPECT_LT(std::stod(rows[0][19]), 1e-4);

  // The resolved config reads back; summary.json and tables.md are there.
  const ExperimentConfig resolved = load_experiment_config(path("out/config.yaml"));
  EXPECT_EQ(resolved.source.path, path("source.txt"));
  EXPECT_EQ(resolved.ground_truth.path, path("gt.txt"));
  EXPECT_EQ(resolved.experiments.size(), 3u);
  const auto j = nlohmann::json::parse(test::read_text(path("out/summary.json")));
  EXPECT_EQ(j["cases_finished"], 10);
  EXPECT_EQ(j["per_experiment"]["ks"]["per_strategy"]["base"]["runs"], 2);
  EXPECT_EQ(j["per_experiment"]["bas"]["levels"].size(), 3u);
  const std::string md = test::read_text(path("out/tables.md"));
  EXPECT_NE(md.find("## ks (k)"), std::string::npos);
  EXPECT_NE(md.find("## bas (basin)"), std::string::npos);
  EXPECT_NE(md.find("**"), std::string::npos);
  // Per-case files for the plots: the Table-1-like k=5 case by default (case 1).
  EXPECT_EQ(
      test::read_text(path("out/history.csv")).rfind("case,experiment,label,strategy,iteration", 0),
      0u);
  EXPECT_NE(test::read_text(path("out/alignment_points.csv")).find("1,ks,k=5,target,"),
            std::string::npos);

  if (!has_matplotlib()) {
    GTEST_SKIP() << "/usr/bin/python3 has no matplotlib: plots not checked";
  }
  for (const char* png : {"ks_violin.png", "yaws_violin.png", "bas_basin.png", "history_case1.png",
                          "alignment_case1.png"}) {
    EXPECT_TRUE(is_png(path(std::string("out/plots/") + png))) << png << "\n" << r.err;
  }
  // The script also runs alone, e.g. for another recorded case name.
  const int rc = std::system(("/usr/bin/python3 " + test::shell_quote(plot_script()) + " " +
                              test::shell_quote(path("out")) + " --case ks/k=5 --quiet")
                                 .c_str());
  EXPECT_EQ(rc, 0);
}

TEST_F(CliExperiment, ABinaryOutsideTheCheckoutAndItsBuildFolderStillPlots) {
  if (!has_matplotlib()) GTEST_SKIP() << "/usr/bin/python3 has no matplotlib";
  // A build folder anywhere (cmake -B ../elsewhere) puts the binary away from scripts/: the
  // binary knows its source checkout.
  fs::create_directories(path("elsewhere/bin"));
  fs::copy_file(LMALIGN_CLI_PATH, path("elsewhere/bin/lmalign"));
  const std::string cfg = config("one.yaml", "  - {name: yaws, type: yaw, yaw_deg: [0, 10]}\n");
  const std::string command = test::shell_quote(path("elsewhere/bin/lmalign")) + " experiment " +
                              test::shell_quote(cfg) + " -o " + test::shell_quote(path("out")) +
                              " >" + test::shell_quote(path("log.txt")) + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << test::read_text(path("log.txt"));
  const std::string log = test::read_text(path("log.txt"));
  EXPECT_EQ(log.find("no plots"), std::string::npos) << log;
  EXPECT_NE(log.find("(drawn by " + plot_script() + ")"), std::string::npos) << log;
  EXPECT_TRUE(is_png(path("out/plots/yaws_violin.png"))) << log;
  // The plots went through the one writer: no temporary folder is left.
  for (const auto& e : fs::directory_iterator(path("out/plots"))) {
    EXPECT_EQ(e.path().filename().string().rfind(".lmalign-plots", 0), std::string::npos);
  }
}

TEST_F(CliExperiment, OnlyRunsTheNamedExperiments) {
  const std::string cfg = config("only.yaml",
                                 "  - {name: ks, type: k, k_values: [1, 5]}\n  - {name: yaws, "
                                 "type: yaw, yaw_deg: [0, 10, 20]}\n",
                                 "ground_truth: gt.txt\nplot_case: ks/k=5\n");
  const test::CliRun r =
      run("experiment " + cfg + " --only yaws -o " + path("out") + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rows = read_results(path("out/results.csv"));
  ASSERT_EQ(rows.size(), 6u);
  for (const auto& row : rows) EXPECT_EQ(row[0], "yaws");
  // The configured plot case is not run: the first case is plotted instead.
  EXPECT_NE(test::read_text(path("out/history.csv")).find("\n0,yaws,yaw=0,"), std::string::npos);
  // An explicit --plot-case must name a case that runs.
  const test::CliRun bad =
      run("experiment " + cfg + " --only yaws --plot-case ks/k=5 -o " + path("o2"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("plot_case 'ks/k=5' names no case"), std::string::npos) << bad.err;
}

TEST_F(CliExperiment, TwoRunsGiveIdenticalCsvsApartFromTheTimeColumn) {
  const std::string cfg = small_config();
  const test::CliRun a = run("experiment " + cfg + " -o " + path("a") + " --threads 1 --no-plots");
  const test::CliRun b = run("experiment " + cfg + " -o " + path("b") + " --threads 2 --no-plots");
  ASSERT_EQ(a.exit_code, 0) << a.err;
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const std::string ca = test::read_text(path("a/results.csv"));
  const std::string cb = test::read_text(path("b/results.csv"));
  EXPECT_EQ(lines_of(ca).size(), 21u);
  EXPECT_EQ(without_time(ca), without_time(cb));
  EXPECT_FALSE(fs::exists(path("a/plots")));
}

TEST_F(CliExperiment, WithoutGroundTruthTheScoreDecides) {
  const std::string cfg = config("nogt.yaml", "  - {name: yaws, type: yaw, yaw_deg: [0, 120]}\n",
                                 "success: {score_m2: 1.0e-6}\n");
  const test::CliRun r = run("experiment " + cfg + " -o " + path("out") + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("no ground truth; success = final score < 1e-06"), std::string::npos)
      << r.out;
  for (const auto& row : read_results(path("out/results.csv"))) {
    EXPECT_EQ(row[22], "score");
    EXPECT_EQ(row[19], "");
    EXPECT_EQ(row[21], std::stod(row[15]) < 1e-6 ? "true" : "false");
  }
}

TEST_F(CliExperiment, PlottingFailureIsAWarningNotAnError) {
  ::setenv("LMALIGN_PYTHON", "/bin/false", 1);
  const test::CliRun r =
      run("experiment " + config("one.yaml", "  - {name: yaws, type: yaw, yaw_deg: [0]}\n") +
          " -o " + path("out"));
  ::unsetenv("LMALIGN_PYTHON");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("warning: plotting failed"), std::string::npos) << r.err;
  EXPECT_EQ(read_results(path("out/results.csv")).size(), 2u);
  EXPECT_TRUE(fs::exists(path("out/tables.md")));
}

TEST_F(CliExperiment, BadInputGivesAOneLineErrorWithFileAndLine) {
  const std::string cfg = config("bad.yaml", "  - name: yaws\n    type: yaw\n    yaw_deg: 30\n");
  const test::CliRun r = run("experiment " + cfg + " -o " + path("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find(cfg + ":8: experiments[0].yaw_deg: expected a list of numbers"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(path("out")));

  const test::CliRun missing = run("experiment " + path("nope.yaml"));
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("nope.yaml"), std::string::npos);

  const test::CliRun only = run("experiment " + small_config() + " --only table9 -o " + path("o"));
  EXPECT_EQ(only.exit_code, 2);
  EXPECT_NE(only.err.find("no experiment named 'table9'"), std::string::npos) << only.err;
}

TEST_F(CliExperiment, SigintMidwayLeavesAValidCsvOfTheFinishedCases) {
  // Enough cases to be interrupted: 8 levels x 30 draws, on one thread.
  const std::string cfg = config("many.yaml",
                                 "  - {name: bas, type: basin, levels: {yaw_deg: [10, 20, 30, 40], "
                                 "translation_m: [0.2, 0.4, 0.6, 0.8]}, samples: 30}\n");
  const std::string out_file = path("run.out"), err_file = path("run.err");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::freopen(out_file.c_str(), "w", stdout);
    std::freopen(err_file.c_str(), "w", stderr);
    ::execl(LMALIGN_CLI_PATH, LMALIGN_CLI_PATH, "experiment", cfg.c_str(), "-o",
            path("out").c_str(), "--threads", "1", "--no-plots", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  // Wait until some cases are in results.csv (polling; nothing is timed), then interrupt.
  bool some = false;
  for (int i = 0; i < 6000 && !some; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (fs::exists(path("out/results.csv")))
      some = lines_of(test::read_text(path("out/results.csv"))).size() >= 3;
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid)
      FAIL() << "finished before it could be interrupted";
  }
  ASSERT_TRUE(some);
  ASSERT_EQ(::kill(pid, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << test::read_text(err_file);
  const std::string out = test::read_text(out_file);
  EXPECT_NE(out.find("interrupted: "), std::string::npos) << out;
  EXPECT_NE(out.find(" of 240 cases finished; results.csv holds them"), std::string::npos) << out;

  // The CSV holds complete cases only: both strategies of each, nothing half-written.
  const auto rows = read_results(path("out/results.csv"));
  ASSERT_GE(rows.size(), 2u);
  EXPECT_LT(rows.size(), 480u);
  EXPECT_EQ(rows.size() % 2, 0u);
  std::map<std::string, std::set<std::string>> strategies;
  for (const auto& row : rows) strategies[row[1]].insert(row[12]);
  for (const auto& [c, s] : strategies) EXPECT_EQ(s.size(), 2u) << "case " << c;
  EXPECT_NE(out.find(std::to_string(strategies.size()) + " of 240 cases finished"),
            std::string::npos)
      << out;
  const auto j = nlohmann::json::parse(test::read_text(path("out/summary.json")));
  EXPECT_TRUE(j["interrupted"].get<bool>());
  for (const auto& entry : fs::directory_iterator(path("out"))) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp."), std::string::npos) << entry.path();
  }
}

/// Starts `lmalign experiment <args>` as a child (stdout/stderr into files) and sends it `sig`
/// once results.csv has at least `min_lines` lines (header included). Returns the exit status;
/// fails the test if the run ended before it could be stopped.
int stop_midway(const std::vector<std::string>& args, const std::string& csv, int sig,
                std::size_t min_lines, const std::string& out_file, const std::string& err_file) {
  std::vector<char*> argv{const_cast<char*>(LMALIGN_CLI_PATH), const_cast<char*>("experiment")};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ADD_FAILURE() << "fork failed";
    return -1;
  }
  if (pid == 0) {
    std::freopen(out_file.c_str(), "w", stdout);
    std::freopen(err_file.c_str(), "w", stderr);
    ::execv(LMALIGN_CLI_PATH, argv.data());
    ::_exit(127);
  }
  // Poll until enough cases are in results.csv (nothing is timed), then stop the run.
  bool some = false;
  for (int i = 0; i < 60000 && !some; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (fs::exists(csv)) some = lines_of(test::read_text(csv)).size() >= min_lines;
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      ADD_FAILURE() << "finished before it could be stopped: " << test::read_text(err_file);
      return -1;
    }
  }
  EXPECT_TRUE(some);
  EXPECT_EQ(::kill(pid, sig), 0);
  int status = 0;
  EXPECT_EQ(::waitpid(pid, &status, 0), pid);
  return status;
}

TEST_F(CliExperiment, SigtermThenResumeGivesTheCsvOfAnUninterruptedRun) {
  // 64 basin draws and 3 yaw cases, 2 strategies each, on one thread: long enough to be stopped.
  const std::string experiments =
      "  - {name: bas, type: basin, levels: {yaw_deg: [10, 40], translation_m: [0.2, 0.6]}, "
      "samples: 16}\n"
      "  - {name: yaws, type: yaw, yaw_deg: [0, 20, 120]}\n";
  const std::string cfg = config("many.yaml", experiments);
  const std::string csv = path("out/results.csv");
  const int status = stop_midway({cfg, "-o", path("out"), "--threads", "1", "--no-plots"}, csv,
                                 SIGTERM, 5, path("run.out"), path("run.err"));
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << test::read_text(path("run.err"));
  const std::string run_out = test::read_text(path("run.out"));
  EXPECT_NE(run_out.find("of 67 cases finished; results.csv holds them"), std::string::npos)
      << run_out;
  EXPECT_NE(run_out.find("lmalign experiment --resume " + path("out")), std::string::npos)
      << run_out;

  // The partial CSV: valid, complete cases only, fewer than all.
  const std::string partial = test::read_text(csv);
  const auto partial_rows = read_results(csv);
  ASSERT_GE(partial_rows.size(), 4u);
  ASSERT_LT(partial_rows.size(), 134u);
  EXPECT_EQ(partial_rows.size() % 2, 0u);
  const std::size_t partial_cases = partial_rows.size() / 2;

  // A different config is refused with one line, and the folder is left as it was.
  const std::string other =
      config("other.yaml",
             "  - {name: bas, type: basin, levels: {yaw_deg: [10, 40], translation_m: "
             "[0.2, 0.6]}, samples: 17}\n  - {name: yaws, type: yaw, yaw_deg: [0, 20, 120]}\n");
  const test::CliRun refused = run("experiment " + other + " --resume " + path("out"));
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_NE(refused.err.find("lmalign: error: --resume '" + path("out") +
                             "': the config differs from the one of the interrupted run"),
            std::string::npos)
      << refused.err;
  EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
  EXPECT_EQ(test::read_text(csv), partial);
  const test::CliRun nothing = run("experiment --resume " + path("nowhere"));
  EXPECT_EQ(nothing.exit_code, 2);
  EXPECT_NE(nothing.err.find("holds no run to resume"), std::string::npos) << nothing.err;

  // Resume (from the folder alone, on two threads): the finished cases are not run again.
  const test::CliRun resumed =
      run("experiment --resume " + path("out") + " --threads 2 --no-plots");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_NE(resumed.out.find("resuming: " + std::to_string(partial_cases) + " cases (" +
                             std::to_string(partial_rows.size()) + " runs) already finished"),
            std::string::npos)
      << resumed.out;
  const std::string after = test::read_text(csv);
  // The rows of the interrupted run are kept byte for byte, wall time included.
  for (const std::string& line : lines_of(partial))
    EXPECT_NE(after.find(line + "\n"), std::string::npos) << line;

  // A run that was never interrupted gives the same CSV: same rows in the same order, every
  // column equal except the documented wall-time column time_s.
  const test::CliRun full = run("experiment " + cfg + " -o " + path("full") + " --no-plots");
  ASSERT_EQ(full.exit_code, 0) << full.err;
  const std::string expected = test::read_text(path("full/results.csv"));
  EXPECT_EQ(lines_of(after).size(), 135u);
  EXPECT_EQ(without_time(after), without_time(expected));
  // tables.md has no timing: identical; summary.json agrees on everything but median_time_s.
  EXPECT_EQ(test::read_text(path("out/tables.md")), test::read_text(path("full/tables.md")));
  auto strip_times = [](nlohmann::json j) {
    std::function<void(nlohmann::json&)> strip = [&](nlohmann::json& x) {
      if (x.is_object()) {
        x.erase("median_time_s");
        for (auto& [k, v] : x.items()) strip(v);
      } else if (x.is_array()) {
        for (auto& v : x) strip(v);
      }
    };
    strip(j);
    return j;
  };
  const auto js = nlohmann::json::parse(test::read_text(path("out/summary.json")));
  const auto jf = nlohmann::json::parse(test::read_text(path("full/summary.json")));
  EXPECT_FALSE(js["interrupted"].get<bool>());
  EXPECT_EQ(strip_times(js), strip_times(jf));
  EXPECT_EQ(test::read_text(path("out/history.csv")), test::read_text(path("full/history.csv")));
  EXPECT_EQ(test::read_text(path("out/alignment_points.csv")),
            test::read_text(path("full/alignment_points.csv")));
  for (const auto& entry : fs::directory_iterator(path("out"))) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp."), std::string::npos) << entry.path();
  }
}

}  // namespace
}  // namespace lmalign
