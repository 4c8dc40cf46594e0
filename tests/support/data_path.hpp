// Locating the real data for integration tests.
//   LMALIGN_DATA (environment) overrides the compiled-in default ../shared/data.
//   Outside CI, missing data skips the test; with CI=true it fails (house rule).
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace lmalign::test {

inline std::string data_dir() {
  if (const char* env = std::getenv("LMALIGN_DATA"); env != nullptr && *env != '\0') return env;
  return LMALIGN_DEFAULT_DATA_DIR;
}

inline std::string data_file(const std::string& relative) { return data_dir() + "/" + relative; }

inline bool running_in_ci() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}

}  // namespace lmalign::test

/// Skips (locally) or fails (CI=true) the current test if `path` does not exist.
#define LMALIGN_REQUIRE_FILE(path)                                                  \
  do {                                                                              \
    if (!std::filesystem::exists(path)) {                                           \
      if (::lmalign::test::running_in_ci()) {                                       \
        FAIL() << "real data missing in CI: " << (path) << " (set LMALIGN_DATA)";   \
      } else {                                                                      \
        GTEST_SKIP() << "real data not found: " << (path) << " (set LMALIGN_DATA)"; \
      }                                                                             \
    }                                                                               \
  } while (0)
