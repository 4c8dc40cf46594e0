// The skeleton both CLI executables share: the root app (its description, --version), parsing,
// and one policy for errors and exit codes (0 success, 2 bad input, 3 internal error).
#pragma once

#include <vector>

#include "commands.hpp"

namespace lmalign::cli {

/// Registers one subcommand on the root app and returns its runner (see commands.hpp).
using CommandAdder = CommandRunner (*)(CLI::App&);

/// Builds the `lmalign` root app with `commands`, parses argv and runs the chosen command.
/// Returns the process exit code: usage errors and lmalign::Error give one line on stderr and 2,
/// other exceptions 3, unwritable standard output 2.
int run_cli(int argc, char** argv, const std::vector<CommandAdder>& commands);

}  // namespace lmalign::cli
