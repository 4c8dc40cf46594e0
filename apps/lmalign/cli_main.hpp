// The skeleton both CLI executables share: the root app (its description, --version), parsing,
// and one policy for errors and exit codes (0 success, 2 any error).
#pragma once

#include <vector>

#include "commands.hpp"

namespace lmalign::cli {

/// Registers one subcommand on the root app and returns its runner (see commands.hpp).
using CommandAdder = CommandRunner (*)(CLI::App&);

/// Builds the `lmalign` root app with `commands`, parses argv and runs the chosen command.
/// Returns the process exit code: every error (a usage error, lmalign::Error, any other
/// exception, out of memory, an unwritable standard output) gives one line on stderr and 2.
int run_cli(int argc, char** argv, const std::vector<CommandAdder>& commands);

/// The executables' last resort (main() installs it): an exception that escapes where it cannot
/// be caught (std::terminate) is one line, "lmalign: error: internal error: ...", and exit code 2
/// rather than an abort. Not installed by run_cli(), so that a fuzzer sees such an abort.
void install_terminate_handler();

}  // namespace lmalign::cli
