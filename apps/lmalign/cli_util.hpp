// Small helpers shared by the CLI subcommands (parsing, output-path checks, JSON values).
#pragma once

#include <signal.h>

#include <array>
#include <atomic>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmalign/core/types.hpp"

namespace lmalign::cli {

/// Parses exactly `count` comma-separated finite numbers, e.g. "0,1,0.4,10,0,22.5".
/// Throws InvalidArgument("<option> \"<text>\": expected ...").
std::vector<double> parse_number_list(const std::string& option, const std::string& text,
                                      std::size_t count, const std::string& expected);

/// Parses --image-size "W,H" (two positive integers, pixels; Bundler's pixels are centred on the
/// image, so its reader needs the size). Throws InvalidArgument naming the option and the text.
std::array<long long, 2> parse_image_size(const std::string& text);

/// True if the two paths name the same file (existing or not).
bool same_file(const std::string& a, const std::string& b);

/// Throws InvalidArgument if `output` names one of `inputs` (an output must never clobber input).
void refuse_output_over_input(const std::string& option, const std::string& output,
                              const std::vector<std::string>& inputs);

/// A double as JSON: a number, or null if not finite (JSON has no inf/NaN).
nlohmann::json json_number(double v);

/// A 4x4 matrix as a JSON array of 4 rows.
nlohmann::json json_matrix(const Isometry3& T);

}  // namespace lmalign::cli

namespace lmalign::cli {

/// The flag set by the first SIGINT/SIGTERM while a StopSignals is alive.
std::atomic<bool>& stop_flag();

/// While alive: the first SIGINT/SIGTERM sets stop_flag() (a long command then stops after the
/// work in flight; every file on disk is complete, being written atomically); a second one ends
/// the process at once. The previous handlers come back on destruction.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

/// The source checkout this executable was built in (the folder holding scripts/), found by
/// walking up from /proc/self/exe; empty when not found (e.g. an installed binary).
std::filesystem::path repository_root();

/// $LMALIGN_PYTHON, else /usr/bin/python3 if executable, else python3 (PATH).
std::string python_interpreter();

/// Runs argv (PATH lookup for argv[0]); returns the exit status, or -1 if it could not run.
int run_process(const std::vector<std::string>& argv);

}  // namespace lmalign::cli
