// Subcommands of the `lmalign` CLI. Each add_*_command() registers its options on `root` and
// returns the function that runs it after parsing. Commands print; the library never does.
// A command returns the process exit code; it may throw lmalign::Error, which main() turns into
// a one-line "lmalign: error: ..." message and exit code 2.
#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace lmalign::cli {

using CommandRunner = std::function<int()>;

CommandRunner add_align_command(CLI::App& root);
CommandRunner add_options_command(CLI::App& root);
CommandRunner add_split_command(CLI::App& root);
CommandRunner add_experiment_command(CLI::App& root);
CommandRunner add_eval_trajectory_command(CLI::App& root);
CommandRunner add_convert_command(CLI::App& root);
CommandRunner add_simulate_command(CLI::App& root);
#ifdef LMALIGN_HAVE_MERGE
CommandRunner add_merge_command(CLI::App& root);
#endif
#ifdef LMALIGN_HAVE_VO
CommandRunner add_build_map_command(CLI::App& root);
#endif
/// `build-map`'s description, shown by lmalign --help and by the helper that runs it.
extern const char* const kBuildMapDescription;

}  // namespace lmalign::cli
