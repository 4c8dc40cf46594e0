// Small helpers shared by the CLI subcommands (parsing, output-path checks, JSON values).
#pragma once

#include <signal.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/presets.hpp"

namespace lmalign::cli {

/// Parses exactly `count` comma-separated finite numbers, e.g. "0,1,0.4,10,0,22.5".
/// Throws InvalidArgument("<option> \"<text>\": expected ...").
std::vector<double> parse_number_list(const std::string& option, const std::string& text,
                                      std::size_t count, const std::string& expected);

/// Adds each --set "KEY=VALUE" to `request` (AlignRequest::add_assignment; the values are read
/// by resolve()). Throws InvalidArgument("--set '<text>': expected KEY=VALUE").
void add_set_options(const std::vector<std::string>& assignments, AlignRequest* request);

/// Parses --image-size "W,H" (two positive integers, pixels; Bundler's pixels are centred on the
/// image, so its reader needs the size). Throws InvalidArgument naming the option and the text.
std::array<long long, 2> parse_image_size(const std::string& text);

/// True if the two paths name the same file (existing or not).
bool same_file(const std::string& a, const std::string& b);

/// Throws InvalidArgument if `output` names one of `inputs` (an output must never clobber input).
void refuse_output_over_input(const std::string& option, const std::string& output,
                              const std::vector<std::string>& inputs);

/// An output file named by an option: {option, path}; an empty path is not given.
using OutputOption = std::pair<std::string, std::string>;

/// Checks a command's output files before any work (io/output_file.hpp check_output_path: a
/// missing directory, a directory, a block device are one-line errors naming the path), refuses
/// one that is an input, and when one is the standard output ("-", /dev/stdout) sends the human
/// summary to standard error from then on (human()). At most one output may be the standard
/// output. Throws InvalidArgument or IoError.
void check_outputs(const std::vector<OutputOption>& outputs,
                   const std::vector<std::string>& inputs = {});

/// Refuses "-" (or a path naming the standard output) for an output folder (-o OUTDIR).
void refuse_standard_output_folder(const std::string& option, const std::string& folder);

/// Where the human summary goes: standard output, or standard error once an output file has
/// claimed standard output (check_outputs).
std::FILE* human_file();
std::ostream& human();
/// printf to human_file().
void say(const char* format, ...) __attribute__((format(printf, 1, 2)));
/// How a "written to" line names an output: "the standard output" for "-", else the path.
std::string output_name(const std::string& path);
/// True once an output file has claimed standard output.
bool standard_output_claimed();

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

/// The source checkout this executable was built from (LMALIGN_SOURCE_DIR, set by CMake),
/// when it still exists; empty otherwise (e.g. a package installed on another machine).
std::filesystem::path source_checkout();

/// A plotting script shipped with lmalign (scripts/NAME): $ENV_VAR if set, else the installed
/// copy (<bin>/../share/lmalign/scripts/NAME, as `make install`, the .deb and pip put it), else
/// the source checkout's (any build folder of it). Empty when none exists.
std::string find_script(const std::string& name, const char* env_var);

/// Runs `script` (with python_interpreter()) with `args` plus `--plots-dir TEMP`, a temporary
/// folder inside `plots_dir` (created if missing), then writes each file it drew into
/// `plots_dir` through the one output writer (io/output_file.hpp) and removes the folder.
/// Returns the script's exit status (-1 if it could not run); on a non-zero status nothing is
/// written. Throws IoError when a plot cannot be written.
int draw_plots(const std::string& script, const std::vector<std::string>& args,
               const std::string& plots_dir);

/// $LMALIGN_PYTHON, else /usr/bin/python3 if executable, else python3 (PATH).
std::string python_interpreter();

/// Runs argv (PATH lookup for argv[0]); returns the exit status, or -1 if it could not run.
int run_process(const std::vector<std::string>& argv);

}  // namespace lmalign::cli
