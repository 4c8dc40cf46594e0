// The CLI-options fuzz oracle, shared by the libFuzzer target (fuzz_cli_options.cpp, which runs
// the CLI's own run_cli() in process) and the regression test that replays
// fuzz/corpus/cli_options/ and fuzz/regressions/cli_options/ through the real `lmalign` binary
// (tests/cli/test_cli_fuzz_regressions.cpp). docs/robustness.md describes it.
//
// Input: lines "KEY VALUE". Each becomes an option of `lmalign align SOURCE TARGET` on two small
// fixed maps (write_cli_fuzz_maps()):
//   displace V -> --displace V        prior-sigma V -> --prior-sigma V   set V -> --set V
//   strategy V -> --strategy V (the first only; at most two, no group; the complete search's
//   presets alone)     k V -> --k V   max-distance V
//   max-iterations V (at most 500: a budget the user chooses is not a hang)
//   set KEY=VALUE: passed unless it raises a work budget above every preset's own
//   (set_keeps_work_bounded(): a count above the largest default of any preset, a yaw step below
//   the smallest; a budget the user raises is not a hang, and an input has 10 s under the
//   sanitizers)
//   guess ROW -> a row of the --initial-guess file (4 rows of 4 numbers; the option is given
//   once the first row is)            truth ROW -> likewise for --ground-truth
// Other lines are ignored; at most kFuzzMaxCliOptions options, values of at most 256 bytes.
// When the strategies run the complete search (the default does), fuzz_search_budget() is added
// last as `--set` (time per input).
//
// For any bytes: the command ends with exit code 0, or 2 and exactly one line on stderr,
// "lmalign: error: ..." (never the CLI's own "lmalign: error: internal error: ..."); no crash,
// sanitizer report, leak or hang.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "default_alignment_check.hpp"  // fuzz_search_budget
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/presets.hpp"
#include "map_reader_check.hpp"  // LMALIGN_FUZZ_CHECK

namespace lmalign::fuzz {

inline constexpr std::size_t kFuzzMaxCliOptions = 12;

/// True when `name` is a built-in preset whose initialiser is the complete search.
inline bool runs_complete_search(const std::string& name) {
  if (!is_preset_name(name)) return false;
  return Pipeline(find_preset(name).spec).settings().has("search.pool");
}

/// False when `setting` ("KEY=VALUE", as --set takes it) raises a work budget of the alignment
/// above every built-in preset's own: a setting counted in "count" (iterations, samples,
/// hypotheses, planes, ...) above the largest default any preset gives it, or a yaw step
/// ("*_step_deg") below the smallest. True for anything else, unknown keys and values the CLI
/// refuses included (the value is read as the CLI reads it, SettingRow::parse).
inline bool set_keeps_work_bounded(const std::string& setting) {
  struct Limit {
    SettingRow row;
    double bound = 0.0;
    bool at_most = true;  // a count: value <= bound; a step: value >= bound
  };
  static const std::map<std::string, Limit> limits = [] {
    std::map<std::string, Limit> out;
    for (const Preset& p : presets()) {
      const Pipeline pipeline(p.spec);
      for (const SettingRow& row : pipeline.settings().table()) {
        const bool count = row.unit == "count";
        const bool step =
            row.key.size() > 9 && row.key.compare(row.key.size() - 9, 9, "_step_deg") == 0;
        if (!count && !step) continue;
        const SettingValue& value = pipeline.settings().value(row.key);  // the preset's
        const double v = std::holds_alternative<long long>(value)
                             ? static_cast<double>(std::get<long long>(value))
                             : std::get<double>(value);
        auto [it, fresh] = out.emplace(row.key, Limit{row, v, count});
        if (!fresh)
          it->second.bound = count ? std::max(it->second.bound, v) : std::min(it->second.bound, v);
      }
    }
    return out;
  }();
  const std::size_t eq = setting.find('=');
  if (eq == std::string::npos) return true;
  const auto it = limits.find(setting.substr(0, eq));
  if (it == limits.end()) return true;
  SettingValue v;
  try {
    v = it->second.row.parse(setting.substr(eq + 1));
  } catch (const Error&) {
    return true;  // the CLI refuses it
  }
  const double x = std::holds_alternative<long long>(v)
                       ? static_cast<double>(std::get<long long>(v))
                   : std::holds_alternative<double>(v) ? std::get<double>(v)
                                                       : std::numeric_limits<double>::quiet_NaN();
  if (std::isnan(x)) return true;
  return it->second.at_most ? x <= it->second.bound : x >= it->second.bound;
}

/// What an input asks for: the options after `align SOURCE TARGET`, with the names of the
/// --initial-guess and --ground-truth files (in the folder given to decode_cli_options), and
/// their contents.
struct CliOptionsInput {
  std::vector<std::string> args;
  std::string initial_guess_text;
  std::string ground_truth_text;
};

inline CliOptionsInput decode_cli_options(const std::string& text, const std::string& dir) {
  CliOptionsInput in;
  std::size_t options = 0;
  bool guess = false, truth = false;
  bool strategy_given = false;
  bool complete_search = true;  // the default, adaptive
  std::size_t start = 0;
  while (start < text.size() && options < kFuzzMaxCliOptions) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    const std::size_t space = line.find(' ');
    if (space == std::string::npos) continue;
    const std::string key = line.substr(0, space);
    const std::string value = line.substr(space + 1, 256);
    static const std::pair<const char*, const char*> kOptions[] = {
        {"displace", "--displace"},
        {"prior-sigma", "--prior-sigma"},
        {"set", "--set"},
        {"strategy", "--strategy"},
        {"k", "--k"},
        {"max-distance", "--max-distance"}};
    const auto* named = std::find_if(std::begin(kOptions), std::end(kOptions),
                                     [&](const auto& o) { return key == o.first; });
    if (named != std::end(kOptions)) {
      // At most two strategies, no group ('paper', 'lmalign', 'all' run several): time per input.
      if (key == "strategy" &&
          (std::count(value.begin(), value.end(), ',') > 1 ||
           value.find("all") != std::string::npos || value.find("paper") != std::string::npos ||
           value.find("lmalign") != std::string::npos)) {
        continue;
      }
      if (key == "set" && !set_keeps_work_bounded(value)) continue;
      if (key == "strategy") {
        // One --strategy, its complete-search presets alone (they get fuzz_search_budget() below).
        if (strategy_given) continue;
        std::size_t heavy = 0, items = 0;
        for (std::size_t from = 0; from <= value.size();) {
          std::size_t to = value.find(',', from);
          if (to == std::string::npos) to = value.size();
          ++items;
          if (runs_complete_search(value.substr(from, to - from))) ++heavy;
          from = to + 1;
        }
        if (heavy != 0 && heavy != items) continue;
        strategy_given = true;
        complete_search = heavy != 0;
      }
      in.args.push_back(named->second);
      in.args.push_back(value);
      ++options;
    } else if (key == "max-iterations") {
      char* rest = nullptr;
      const double v = std::strtod(value.c_str(), &rest);
      if (!(v > 500.0)) {  // non-numbers too: the CLI refuses them
        in.args.push_back("--max-iterations");
        in.args.push_back(value);
        ++options;
      }
    } else if (key == "guess" || key == "truth") {
      const bool is_guess = key == "guess";
      (is_guess ? in.initial_guess_text : in.ground_truth_text) += value + "\n";
      bool& given = is_guess ? guess : truth;
      if (!given) {
        given = true;
        in.args.push_back(is_guess ? "--initial-guess" : "--ground-truth");
        in.args.push_back(dir + (is_guess ? "/guess.txt" : "/truth.txt"));
        ++options;
      }
    }
  }
  if (complete_search) {
    // Last, so that they win over the input's own --set of the same keys.
    for (const auto& [key, value] : fuzz_search_budget()) {
      in.args.push_back("--set");
      in.args.push_back(key + "=" + std::to_string(value));
    }
  }
  return in;
}

/// Writes the input's files into `dir` (the two maps must be there: write_cli_fuzz_maps()).
inline void write_cli_fuzz_files(const CliOptionsInput& in, const std::string& dir) {
  std::ofstream(dir + "/guess.txt", std::ios::binary) << in.initial_guess_text;
  std::ofstream(dir + "/truth.txt", std::ios::binary) << in.ground_truth_text;
}

/// Writes dir/source.txt and dir/target.txt: 80 landmarks of a room (a floor, a wall, clutter)
/// seen by four frames, the source turned by 20 degrees and moved 0.3 m.
inline void write_cli_fuzz_maps(const std::string& dir) {
  Map target;
  for (int f = 0; f < 4; ++f) {
    Frame fr;
    fr.id = f;
    fr.p_world_camera = Vec3(1.0 + f, 1.5, 1.2);
    // Cameras looking along +y, x right, y down: their up axis is +z.
    fr.q_world_camera = Quat(Eigen::AngleAxisd(-kPi / 2.0, Vec3::UnitX()));
    target.frames.push_back(fr);
  }
  unsigned state = 12345u;
  auto u = [&state] {
    state = state * 1103515245u + 12345u;
    return static_cast<double>((state >> 8) & 0xffff) / 65536.0;
  };
  for (int i = 0; i < 80; ++i) {
    Landmark l;
    l.id = i;
    const double pick = u();
    l.p_world = Vec3(4.0 * u(), 3.0 * u(), 2.5 * u());
    if (pick < 0.4) l.p_world.z() = 0.0;
    if (pick >= 0.4 && pick < 0.6) l.p_world.y() = 3.0;
    l.cov_world_m2 = Mat3::Identity() * (1e-4 * (1.0 + u()));
    l.observations = {{i % 4, 300.0, 200.0}, {(i + 1) % 4, 310.0, 205.0}};
    target.landmarks.push_back(l);
  }
  const Isometry3 T_target_source = pose_from_xyz_rpy_deg(0.3, -0.2, 0.0, 0.0, 0.0, 20.0);
  write_map(dir + "/target.txt", target);
  write_map(dir + "/source.txt", transform_map(target, T_target_source.inverse()));
}

/// The oracle on one run's outcome.
inline void check_cli_outcome(int exit_code, const std::string& err) {
  if (exit_code != 0 && exit_code != 2)
    std::fprintf(stderr, "exit %d: %s\n", exit_code, err.c_str());
  LMALIGN_FUZZ_CHECK(exit_code == 0 || exit_code == 2, "exit code neither 0 nor 2");
  if (exit_code == 2) {
    const bool one_line = err.rfind("lmalign: error: ", 0) == 0 && err.find('\n') == err.size() - 1;
    if (!one_line) std::fprintf(stderr, "stderr: %s\n", err.c_str());
    LMALIGN_FUZZ_CHECK(one_line, "the error is not one line starting 'lmalign: error: '");
    // The CLI's internal error begins its line so (apps/lmalign/cli_main.cpp). The words alone
    // may be the user's own text echoed back: a setting named "seinternal errorch..." (a 7-minute
    // run of this target, 2026-11-28; fuzz/regressions/cli_options/).
    LMALIGN_FUZZ_CHECK(err.rfind("lmalign: error: internal error", 0) != 0, "an internal error");
  }
}

}  // namespace lmalign::fuzz
