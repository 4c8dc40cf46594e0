// The experiment-config fuzz oracle, shared by the libFuzzer target (fuzz_experiment_config.cpp)
// and the regression test that replays fuzz/regressions/experiment_config/
// (tests/unit/test_degenerate_fuzz_regressions.cpp). docs/robustness.md describes it.
//
// For any bytes:
//   - parse_experiment_config either throws lmalign::Error or returns a config. Any other
//     exception (yaml-cpp's included), a crash, a sanitizer report, a leak or a hang is a bug.
//   - An accepted config is a fixed point of resolved_config_yaml: the resolved YAML parses again
//     and resolves to the same text.
//   - expand_cases on it either throws lmalign::Error or returns cases with finite
//     displacements and k in [1, 4096].
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "map_reader_check.hpp"  // LMALIGN_FUZZ_CHECK, is_proper_rigid

namespace lmalign::fuzz {

inline void check_experiment_config_bytes(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  ConfigLoadOptions options;
  options.data_dir = "/data";
  ExperimentConfig config;
  try {
    config = parse_experiment_config(text, "fuzz.yaml", "/fuzz", options);
  } catch (const Error&) {
    return;  // a clear refusal is a correct outcome; anything else propagates
  }

  const std::string resolved = resolved_config_yaml(config);
  std::string again;
  try {
    again = resolved_config_yaml(parse_experiment_config(resolved, "fuzz.yaml", "/fuzz", options));
  } catch (const Error& e) {
    std::fprintf(stderr, "resolved config rejected: %s\n--- resolved:\n%s\n", e.what(),
                 resolved.c_str());
    LMALIGN_FUZZ_CHECK(false, "resolved_config_yaml output does not parse again");
  }
  if (again != resolved) {
    std::fprintf(stderr, "--- first:\n%s\n--- second:\n%s\n", resolved.c_str(), again.c_str());
    LMALIGN_FUZZ_CHECK(false, "resolved_config_yaml is not a fixed point");
  }

  // A small fixed source for basin draws about a landmark or the centroid.
  const Points3 source = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 2, 0.5), Vec3(-1, 1, 3)};
  try {
    const std::vector<Case> cases = expand_cases(config, source);
    for (const Case& c : cases) {
      LMALIGN_FUZZ_CHECK(is_proper_rigid(c.D),
                         "a case displacement is not a finite rigid transform");
      LMALIGN_FUZZ_CHECK(c.k >= 1 && c.k <= 4096, "a case has k outside [1, 4096]");
      LMALIGN_FUZZ_CHECK(!c.strategies.empty(), "a case has no strategy");
    }
  } catch (const Error&) {
    // e.g. a plot case or source requirement the config cannot meet: a clear error.
  }
}

}  // namespace lmalign::fuzz
