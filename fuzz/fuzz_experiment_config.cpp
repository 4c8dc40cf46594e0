// libFuzzer target: the YAML experiment-config parser (parse_experiment_config), with the oracle
// of experiment_config_check.hpp. See docs/robustness.md.
#include <cstddef>
#include <cstdint>

#include "experiment_config_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lmalign::fuzz::check_experiment_config_bytes(data, size);
  return 0;
}
