// Running the real `lmalign` binary from tests (LMALIGN_CLI_PATH), capturing exit code, stdout
// and stderr, in a fresh temporary directory per test.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "support/cli_path.hpp"

namespace lmalign::test {

struct CliRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

/// Single-quotes `s` for /bin/sh.
inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// exit 2 with exactly one line on stderr, "lmalign: error: ...", that contains `expect`.
inline void expect_one_line_error(const CliRun& r, const std::string& expect,
                                  const std::string& what) {
  EXPECT_EQ(r.exit_code, 2) << what << "\nstderr: " << r.err;
  EXPECT_EQ(r.err.rfind("lmalign: error: ", 0), 0u) << what << "\nstderr: " << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << what << " not one line: " << r.err;
  EXPECT_NE(r.err.find(expect), std::string::npos)
      << what << ": expected '" << expect << "' in: " << r.err;
}

/// A test fixture with a private temporary directory and a way to run the CLI.
class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("lmalign_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->test_suite_name() + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Runs `lmalign <args>` (args already shell-quoted as needed).
  CliRun run(const std::string& args) const { return run_with_env("", args); }

  /// Runs `env <assignments> lmalign <args>`, e.g. assignments "LD_DEBUG=libs".
  CliRun run_with_env(const std::string& assignments, const std::string& args) const {
    const std::string out = path(".stdout"), err = path(".stderr");
    const std::string command = (assignments.empty() ? "" : "env " + assignments + " ") +
                                shell_quote(LMALIGN_CLI_PATH) + " " + args + " >" +
                                shell_quote(out) + " 2>" + shell_quote(err) + " </dev/null";
    const int status = std::system(command.c_str());
    CliRun r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = read_text(out);
    r.err = read_text(err);
    return r;
  }

  std::filesystem::path dir_;
};

}  // namespace lmalign::test
