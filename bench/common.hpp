// Shared by the benchmark executables (bench/*.cpp): the real pair, the Table 1 setting, time and
// memory probes, and the one-line JSON record each run prints. Nothing here needs PCL or Open3D.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign::bench {

// ---- where the real pair is

inline std::string data_dir() {
  if (const char* env = std::getenv("LMALIGN_DATA"); env != nullptr && *env != '\0') return env;
  return LMALIGN_DEFAULT_DATA_DIR;
}
inline std::string pair_file(const char* name) {
  return data_dir() + "/tum_fr1_desk/ground_truth_pair/" + name;
}

/// The paper's Table 1 displacement: x=0 y=1 z=0.4 m, roll=10 pitch=0 yaw=22.5 deg, applied to
/// the source about the world origin (method.md §5).
inline Isometry3 table1_displacement() { return pose_from_xyz_rpy_deg(0, 1, 0.4, 10, 0, 22.5); }

/// The real pair, source displaced by Table 1, with the target's observation weights (the
/// paper's best weighted strategy).
struct RealPair {
  Points3 source;  // desk_gt_a, displaced
  Points3 target;  // desk_gt_b
  std::vector<double> target_weights;
};
inline RealPair load_real_pair() {
  const Map a = read_map(pair_file("desk_gt_a.txt"));
  const Map b = read_map(pair_file("desk_gt_b.txt"));
  RealPair p;
  p.source = transform_points(table1_displacement(), a.positions());
  p.target = b.positions();
  p.target_weights = compute_weights(b, WeightKind::kObservations);
  return p;
}

/// The paper's preset of `weight` (base for kUniform), forced to run `iterations` iterations
/// (PCL's convergence tests off), k = 5, with exact neighbour reuse on or off: the timed path of
/// `make bench`, through the one entry point align(preset) every front end calls.
inline AlignRequest forced_paper_request(int iterations, bool reuse, bool scored) {
  AlignRequest r;
  r.k = 5;
  r.max_iterations = iterations;
  r.record_history = scored;  // and the score at every iteration, as the paper timed
  r.add_assignment("schedule.absolute_mse_epsilon_m2=-1");                    // never fires
  r.add_assignment("schedule.max_iterations_similar_transforms=1073741824");  // nor this
  r.add_assignment(std::string("match.reuse_neighbours=") + (reuse ? "true" : "false"));
  return r;
}
inline const char* paper_preset_name(WeightKind weight) {
  return weight == WeightKind::kUniform        ? "base"
         : weight == WeightKind::kCovariance   ? "covariance"
         : weight == WeightKind::kObservations ? "observations"
                                               : "distance";
}

// ---- memory: the kernel's resident-set counters (kB in /proc/self/status)

inline std::size_t status_kb(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::size_t len = std::strlen(key);
  while (std::getline(in, line)) {
    if (line.compare(0, len, key) == 0 && line.size() > len && line[len] == ':') {
      return std::strtoull(line.c_str() + len + 1, nullptr, 10);
    }
  }
  return 0;
}
inline std::size_t rss_bytes() { return status_kb("VmRSS") * 1024; }
inline std::size_t peak_rss_bytes() { return status_kb("VmHWM") * 1024; }
/// Resets VmHWM to the current RSS (Linux >= 4.0), so that a later peak_rss_bytes() is the peak of
/// what ran in between. Returns false if the kernel refused.
inline bool reset_peak_rss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

// ---- time

inline double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

// ---- command line: <exe> --config NAME [--reps R] [--iterations N]

struct Args {
  std::string config;
  int reps = 7;
  int iterations = 150;
  std::map<std::string, std::string> extra;  // other --key value pairs
};
inline Args parse_args(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--config") {
      a.config = value;
    } else if (key == "--reps") {
      a.reps = std::max(1, std::atoi(value.c_str()));
    } else if (key == "--iterations") {
      a.iterations = std::max(1, std::atoi(value.c_str()));
    } else if (key.rfind("--", 0) == 0) {
      a.extra[key.substr(2)] = value;
    } else {
      throw std::invalid_argument("unexpected argument " + key);
    }
  }
  if (a.config.empty()) throw std::invalid_argument("missing --config NAME");
  return a;
}

/// The body of a configuration executable's main(): run(parse_args(argv)); an exception is one
/// line "program: what" on stderr and exit code 2.
template <typename Run>
int run_main(const char* program, int argc, char** argv, Run&& run) {
  try {
    return run(parse_args(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return 2;
  }
}

// ---- one measured configuration

/// What one run of a configuration reports.
struct RunResult {
  int iterations = 0;
  double final_score_m2 = 0.0;
};

/// Runs `run` once cold (its memory measured: the peak RSS above the RSS before it), then `reps`
/// times for time; prints one JSON object on stdout. `fields` adds "key": value pairs (values
/// already JSON).
inline int measure(const std::string& config, const std::string& peer,
                   const std::string& description, int reps, const std::function<RunResult()>& run,
                   const std::vector<std::pair<std::string, std::string>>& fields = {}) {
  const bool peak_reset = reset_peak_rss();
  const std::size_t rss_before = rss_bytes();
  const double t0 = now_s();
  const RunResult first = run();
  const double cold_s = now_s() - t0;
  const std::size_t peak = peak_rss_bytes();
  std::vector<double> times;
  RunResult r = first;
  for (int i = 0; i < reps; ++i) {
    const double t = now_s();
    r = run();
    times.push_back(now_s() - t);
  }
  const double med = median(times);
  std::printf(
      "{\"config\": \"%s\", \"peer\": \"%s\", \"description\": \"%s\", \"iterations\": %d, "
      "\"final_score_m2\": %.17g, \"total_s\": %.9g, \"per_iteration_s\": %.9g, "
      "\"min_total_s\": %.9g, \"cold_total_s\": %.9g, \"reps\": %d, \"times_s\": [",
      config.c_str(), peer.c_str(), description.c_str(), r.iterations, r.final_score_m2, med,
      r.iterations > 0 ? med / r.iterations : 0.0, *std::min_element(times.begin(), times.end()),
      cold_s, reps);
  for (std::size_t i = 0; i < times.size(); ++i) std::printf("%s%.9g", i ? ", " : "", times[i]);
  std::printf(
      "], \"peak_rss_bytes\": %zu, \"rss_before_bytes\": %zu, \"added_peak_rss_bytes\": %zu, "
      "\"peak_rss_reset\": %s",
      peak, rss_before, peak > rss_before ? peak - rss_before : 0, peak_reset ? "true" : "false");
  for (const auto& [k, v] : fields) std::printf(", \"%s\": %s", k.c_str(), v.c_str());
  std::printf("}\n");
  std::fflush(stdout);
  if (first.iterations != r.iterations) return 1;
  return 0;
}

}  // namespace lmalign::bench
